"""Run summaries: distance travelled, heading change and velocity-tracking errors (appendix Table 7 style).

All from the log's ground-truth base pose (simulation), in the robot's starting heading frame:

* ``displacement_m``: final minus initial torso position (x forward, y left at the start), m;
* ``yaw_change_rad``: unwrapped heading change, rad;
* tracking: position, linear- and angular-velocity errors of `toddlerbot.runtime.tracking.tracking_errors`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.tracking import heading, tracking_errors


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
    falls: int = 0
    """Falls detected (`fell`: the last one was not recovered from)."""
    recoveries: int = 0
    """Falls the recovery policy got the robot up from (``--on-fall get-up``)."""

    def to_dict(self) -> dict:
        return asdict(self)

    def motion_text(self) -> str:
        """Where the torso went and how well it tracked, two lines."""
        t, (dx, dy) = self.tracking, self.displacement_m
        return (f"displacement ({dx:+.3f}, {dy:+.3f}) m, path {self.distance_m:.3f} m, yaw change "
                f"{self.yaw_change_rad:+.3f} rad\ntracking errors: position {t.position_m:.3f} m, linear velocity "
                f"{t.lin_vel_mps:.3f} m/s, angular velocity {t.ang_vel_radps:.3f} rad/s")


def summarize(log: RunLog, fell: bool, fall_time: float | None, window_s: float = WalkConfig.cycle_time,
              falls: int = 0, recoveries: int = 0) -> RunSummary:
    dt = log.control_dt
    pos = log.base_pos[:, :2]
    yaw = np.unwrap(heading(log.base_quat))
    c0, s0 = np.cos(yaw[0]), np.sin(yaw[0])
    start_rot = np.array([[c0, s0], [-s0, c0]])  # world -> start heading
    rel = (pos - pos[0]) @ start_rot.T
    errors = tracking_errors(log.time, log.command, log.base_pos, log.base_quat, fell, window_s=window_s)
    return RunSummary(
        policy=log.policy,
        duration_s=float(len(log.time) * dt),
        fell=fell,
        fall_time_s=fall_time,
        displacement_m=[float(rel[-1, 0]), float(rel[-1, 1])],
        distance_m=float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1))),
        yaw_change_rad=float(yaw[-1] - yaw[0]),
        tracking=Tracking(position_m=errors.position_m, lin_vel_mps=errors.lin_vel_mps,
                          ang_vel_radps=errors.ang_vel_radps),
        mean_compute_ms=float(np.mean(log.compute_time) * 1e3),
        falls=falls,
        recoveries=recoveries,
    )
