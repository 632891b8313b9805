"""Velocity-tracking evaluation in the CPU simulator (appendix Table 7); numpy + MuJoCo only, no JAX.

A policy walks through a fixed schedule of velocity commands (`DEFAULT_COMMANDS`) on `MuJoCoRobot` with the
runtime's runner. From the logged ground-truth torso pose we compute, over the run (until a fall):

* position error, m: mean distance between the torso's floor position and the commanded path (the command
  integrated from the start pose: body-frame velocities rotated by the integrated commanded yaw);
* linear-velocity error, m/s: mean norm of (achieved - commanded) horizontal velocity in the torso's yaw frame;
* angular-velocity error, rad/s: mean |achieved - commanded| yaw rate.

Achieved velocities are central differences of the torso pose averaged over ``window_s`` (one gait cycle by
default), which removes the in-cycle sway that no walking gait avoids; the first ``settle_s`` after each command
change are excluded from the velocity errors (the robot needs a step to respond).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import save_figure
from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import CONTROL_DT

if TYPE_CHECKING:
    from toddlerbot.sim.terrain import TerrainSpec

DEFAULT_COMMANDS = "0:0,0,0; 1:0.1,0,0; 6:0.05,0,0; 10:0,0,0; 12:0,0.05,0; 16:0,0,0.3; 20:0.1,0,0.2; 24:0,0,0"
"""The default evaluation schedule (runtime command syntax, 26 s), inside the trained command ranges: stand, walk
forward at 0.1 then 0.05 m/s, stop, side-step, turn in place, walk on a curve, stop."""
DEFAULT_SECONDS = 26.0
TABLE7_SIM = (0.082, 0.016, 0.056)
"""Appendix Table 7, simulation: position m, linear velocity m/s, angular velocity rad/s."""
TRACKING_BARS = tuple(1.5 * x for x in TABLE7_SIM)
"""What a walking policy must track within (issue 19): 1.5 x `TABLE7_SIM`."""


@dataclass(frozen=True)
class TrackingResult:
    position_m: float
    lin_vel_mps: float
    ang_vel_radps: float
    falls: int
    duration_s: float
    """Simulated time until the end or the fall."""
    time: np.ndarray
    command: np.ndarray
    """(T, 3) commanded vx, vy, yaw rate."""
    achieved: np.ndarray
    """(T, 3) achieved vx, vy (yaw frame) and yaw rate (window-averaged; NaN near the ends)."""

    def summary(self) -> dict[str, float | int]:
        return {"position_m": self.position_m, "lin_vel_mps": self.lin_vel_mps, "ang_vel_radps": self.ang_vel_radps,
                "falls": self.falls, "duration_s": self.duration_s}


def heading(quat: np.ndarray) -> np.ndarray:
    """Yaw (rad, ZYX Euler angles) of w, x, y, z quaternions (..., 4); NaN where a quaternion is not finite (the
    base pose of hardware logs)."""
    quat = np.asarray(quat, dtype=float)
    rows = quat.reshape(-1, 4)
    yaw = np.full(len(rows), np.nan)
    finite = np.isfinite(rows).all(axis=1)
    if finite.any():
        yaw[finite] = Rotation.from_quat(rows[finite], scalar_first=True).as_euler("ZYX")[:, 0]
    return yaw.reshape(quat.shape[:-1])


def tracking_errors(time: np.ndarray, command: np.ndarray, base_pos: np.ndarray, base_quat: np.ndarray, fell: bool,
                    window_s: float = WalkConfig.cycle_time, settle_s: float = 1.0) -> TrackingResult:
    """Tracking errors of one logged run (see the module docstring); arrays are per control step."""
    dt = float(np.median(np.diff(time))) if len(time) > 1 else CONTROL_DT
    yaw = np.unwrap(heading(base_quat))
    # commanded path: integrate body-frame command along the commanded heading
    cmd_yaw = yaw[0] + np.concatenate([[0.0], np.cumsum(command[:-1, 2]) * dt])
    world_cmd = np.stack([np.cos(cmd_yaw) * command[:, 0] - np.sin(cmd_yaw) * command[:, 1],
                          np.sin(cmd_yaw) * command[:, 0] + np.cos(cmd_yaw) * command[:, 1]], axis=1)
    cmd_path = base_pos[0, :2] + np.concatenate([[np.zeros(2)], np.cumsum(world_cmd[:-1] * dt, axis=0)])
    position = float(np.mean(np.linalg.norm(base_pos[:, :2] - cmd_path, axis=1)))

    half = max(1, round(window_s / dt / 2))
    achieved = np.full((len(time), 3), np.nan)
    if len(time) > 2 * half:
        mid = slice(half, len(time) - half)
        dpos = (base_pos[2 * half:, :2] - base_pos[: -2 * half, :2]) / (2 * half * dt)
        yaw_mid = yaw[mid]
        achieved[mid, 0] = np.cos(yaw_mid) * dpos[:, 0] + np.sin(yaw_mid) * dpos[:, 1]
        achieved[mid, 1] = -np.sin(yaw_mid) * dpos[:, 0] + np.cos(yaw_mid) * dpos[:, 1]
        achieved[mid, 2] = (yaw[2 * half:] - yaw[: -2 * half]) / (2 * half * dt)
    changes = np.flatnonzero(np.any(np.diff(command, axis=0) != 0, axis=1)) + 1
    steady = np.ones(len(time), dtype=bool)
    for i in changes:
        steady[(time >= time[i]) & (time < time[i] + settle_s)] = False
    # velocity windows must not straddle a command change either
    valid = steady & np.all(np.isfinite(achieved), axis=1)
    for i in changes:
        valid[max(0, i - half): i + half] = False
    if valid.any():
        lin = float(np.mean(np.linalg.norm(achieved[valid, :2] - command[valid, :2], axis=1)))
        ang = float(np.mean(np.abs(achieved[valid, 2] - command[valid, 2])))
    else:
        lin = ang = float("nan")
    return TrackingResult(position, lin, ang, int(fell), float(time[-1] - time[0] + dt) if len(time) else 0.0,
                          time, command, achieved)


def evaluate_policy(description: RobotDescription, policy_name: str, commands: str = DEFAULT_COMMANDS,
                    seconds: float = DEFAULT_SECONDS, weights: Path | None = None, terrain: TerrainSpec | None = None,
                    terrain_seed: int = 0, **options: object) -> TrackingResult:
    """Run a registered walking policy (e.g. ``walk-rl``, ``walk-zmp``: one with a command reach; ``options`` for
    its factory, e.g. walk-rl's ``symmetric``) through a command schedule on the simulated robot of `description`
    (its fitted motor parameters included), on ``terrain`` drawn from ``terrain_seed`` (None: the flat floor), and
    score it."""
    from toddlerbot.policies import make_policy
    from toddlerbot.runtime.commands import CommandSchedule
    from toddlerbot.runtime.runner import run_policy
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot
    from toddlerbot.sim.terrain import terrain_model

    schedule = CommandSchedule.parse(commands, source="--commands")
    robot = MuJoCoRobot(description, model=None if terrain is None else terrain_model(description, terrain,
                                                                                      terrain_seed))
    policy = make_policy(policy_name, robot, weights=weights, **options)
    if policy.command_reach is None:
        policy.close()
        raise ToddlerbotError(f"policy {policy_name!r} does not follow velocity commands; tracking needs a walking "
                              "policy (walk-rl, walk-zmp or a registered one with a command reach)")
    result = run_policy(robot, policy, schedule, seconds, stop_on_fall=True)
    log = result.log
    return tracking_errors(np.asarray(log.time), np.asarray(log.command), np.asarray(log.base_pos),
                           np.asarray(log.base_quat), result.fell)


def plot_velocity_tracking(result: TrackingResult, title: str, path: Path) -> Path:
    """Commanded versus achieved vx, vy and yaw rate over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for ax, i, label in zip(axes, range(3), ("vx [m/s]", "vy [m/s]", "yaw rate [rad/s]"), strict=True):
        ax.plot(result.time, result.command[:, i], "k--", label="commanded")
        ax.plot(result.time, result.achieved[:, i], "C0", label="achieved")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[0].set_title(f"{title}: position {result.position_m:.3f} m, lin vel {result.lin_vel_mps:.3f} m/s, "
                      f"ang vel {result.ang_vel_radps:.3f} rad/s, falls {result.falls}")
    axes[-1].set_xlabel("time [s]")
    return save_figure(fig, path, dpi=110)
