"""Run summaries: distance travelled, heading change and velocity-tracking errors (appendix Table 7 style).

All from the log's ground-truth base pose (simulation), in the robot's starting heading frame:

* ``displacement_m``: final minus initial torso position (x forward, y left at the start), m;
* ``yaw_change_rad``: unwrapped heading change, rad;
* tracking (means over the run):
  - ``position_m``: distance between the torso's planar path and the path the commands integrate to
    (both from the start pose), m;
  - ``lin_vel_mps``: norm of commanded minus actual planar velocity in the heading frame, m/s;
  - ``ang_vel_radps``: |commanded minus actual yaw rate|, rad/s.
  Velocities are averaged over ``window_s`` (default 0.72 s, one gait cycle) so the within-step sway of a
  walking gait does not count as a tracking error.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from toddlerbot.runtime.log import RunLog


@dataclass(frozen=True)
class Tracking:
    position_m: float
    lin_vel_mps: float
    ang_vel_radps: float


@dataclass(frozen=True)
class RunSummary:
    policy: str
    duration_s: float
    fell: bool
    fall_time_s: float | None
    displacement_m: list[float]
    distance_m: float
    yaw_change_rad: float
    tracking: Tracking
    mean_compute_ms: float
    """Mean policy + backend time per control step."""

    def to_dict(self) -> dict:
        return asdict(self)


def heading(quat: np.ndarray) -> np.ndarray:
    """Yaw (rad) of w, x, y, z quaternions (..., 4)."""
    w, x, y, z = np.moveaxis(quat, -1, 0)
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _window_mean(values: np.ndarray, n: int) -> np.ndarray:
    kernel = np.ones(n) / n
    return np.stack([np.convolve(values[:, i], kernel, mode="valid") for i in range(values.shape[1])], axis=1)


def summarize(log: RunLog, fell: bool, fall_time: float | None, window_s: float = 0.72) -> RunSummary:
    dt = log.control_dt
    pos = log.base_pos[:, :2]
    yaw = np.unwrap(heading(log.base_quat))
    c0, s0 = np.cos(yaw[0]), np.sin(yaw[0])
    start_rot = np.array([[c0, s0], [-s0, c0]])  # world -> start heading
    rel = (pos - pos[0]) @ start_rot.T
    # path the commands integrate to, in the start heading frame
    cmd = log.command
    cmd_yaw = np.concatenate([[0.0], np.cumsum(cmd[:-1, 2] * dt)])
    cmd_vel = np.stack([np.cos(cmd_yaw) * cmd[:, 0] - np.sin(cmd_yaw) * cmd[:, 1],
                        np.sin(cmd_yaw) * cmd[:, 0] + np.cos(cmd_yaw) * cmd[:, 1]], axis=1)
    cmd_path = np.concatenate([[[0.0, 0.0]], np.cumsum(cmd_vel[:-1] * dt, axis=0)])
    position_err = float(np.mean(np.linalg.norm(rel - cmd_path, axis=1)))
    n = max(1, min(len(pos) - 1, round(window_s / dt)))
    if len(pos) > n:
        vel_world = (pos[n:] - pos[:-n]) / (n * dt)
        yaw_mid = yaw[n // 2 : n // 2 + len(vel_world)]
        c, s = np.cos(yaw_mid), np.sin(yaw_mid)
        vel_body = np.stack([c * vel_world[:, 0] + s * vel_world[:, 1], -s * vel_world[:, 0] + c * vel_world[:, 1]], 1)
        yaw_rate = (yaw[n:] - yaw[:-n]) / (n * dt)
        cmd_avg = _window_mean(cmd, n + 1)[: len(vel_body)]
        lin_err = float(np.mean(np.linalg.norm(vel_body - cmd_avg[:, :2], axis=1)))
        ang_err = float(np.mean(np.abs(yaw_rate - cmd_avg[:, 2])))
    else:
        lin_err = ang_err = float("nan")
    return RunSummary(
        policy=log.policy,
        duration_s=float(len(log.time) * dt),
        fell=fell,
        fall_time_s=fall_time,
        displacement_m=[float(rel[-1, 0]), float(rel[-1, 1])],
        distance_m=float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1))),
        yaw_change_rad=float(yaw[-1] - yaw[0]),
        tracking=Tracking(position_m=position_err, lin_vel_mps=lin_err, ang_vel_radps=ang_err),
        mean_compute_ms=float(np.mean(log.compute_time) * 1e3),
    )
