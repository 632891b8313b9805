"""Sim versus real: replay a run log (e.g. from ``toddlerbot hw run``) in the simulator and compare.

The simulator starts from the logged first state (motor angles and speeds; the output joints from the
transmission map; the base at the home pose standing on the floor, since a real robot logs no ground-truth base
pose) and then receives the logged motor targets and firmware gains, each held for the logged interval to the
next step (physics substeps = interval / timestep, so a real run's timing jitter is reproduced). Compared per
motor and overall: position error (deg) and velocity error (rad/s) between simulated and logged motors, at the
logged observation times. For a walking run (non-zero velocity commands), the appendix's Table 7 tracking
errors are computed for the simulated robot, and for the logged one when it has a ground-truth base pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.tracking import TrackingResult, tracking_errors
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig


class CompareError(ToddlerbotError):
    """The run log cannot be replayed on this robot description."""


@dataclass(frozen=True)
class MotorError:
    motor: str
    position_mae_deg: float
    position_max_deg: float
    velocity_mae: float
    """rad/s."""


@dataclass(frozen=True)
class Comparison:
    motors: list[MotorError]
    position_mae_deg: float
    """Over all motors and steps."""
    velocity_mae: float
    """rad/s, over all motors and steps."""
    time: np.ndarray
    """(n,) s from the first step, as replayed."""
    real_pos: np.ndarray
    """(n, m) logged motor angles, rad."""
    sim_pos: np.ndarray
    """(n, m) simulated motor angles at the same times, rad."""
    sim_tracking: TrackingResult | None
    real_tracking: TrackingResult | None
    """None unless the run was a walking run (and, for the real one, has a ground-truth base pose)."""
    gains_logged: bool
    """False for logs without motor_kp/kd (the spec's gains were replayed instead)."""

    def to_json(self) -> dict:
        def tracking(t: TrackingResult | None) -> dict | None:
            return None if t is None else t.summary()

        return {
            "position_mae_deg": self.position_mae_deg, "velocity_mae_radps": self.velocity_mae,
            "gains_logged": self.gains_logged, "steps": len(self.time),
            "motors": [{"motor": e.motor, "position_mae_deg": e.position_mae_deg,
                        "position_max_deg": e.position_max_deg, "velocity_mae_radps": e.velocity_mae}
                       for e in self.motors],
            "tracking": {"sim": tracking(self.sim_tracking), "real": tracking(self.real_tracking)},
        }


def _start_state(robot: MuJoCoRobot, description: RobotDescription, motor_pos: np.ndarray,
                 motor_vel: np.ndarray) -> None:
    m, d = robot.model, robot.data
    joint_pos = description.transmission.matrix @ motor_pos
    joint_vel = description.transmission.matrix @ motor_vel
    for names, pos, vel in ((description.joint_names, joint_pos, joint_vel),
                            (description.motor_names, motor_pos, motor_vel)):
        for name, q, v in zip(names, pos, vel, strict=True):
            joint = m.joint(name)
            d.qpos[joint.qposadr[0]], d.qvel[joint.dofadr[0]] = q, v
    mujoco.mj_forward(m, d)


def replay_in_sim(log: RunLog, description: RobotDescription) -> Comparison:
    """Replay ``log`` on the simulated ``description`` and compare (see the module docstring)."""
    if tuple(log.motor_names) != tuple(description.motor_names):
        raise CompareError(f"the log's motors ({len(log.motor_names)}: {', '.join(log.motor_names[:3])}, ...) are "
                           f"not this robot's ({len(description.motor_names)} motors)")
    n = len(log.time)
    if n < 2:
        raise CompareError(f"the log has {n} step(s); need at least 2 to compare")
    robot = MuJoCoRobot(description, SimConfig(control_dt=log.control_dt))
    robot.reset()
    _start_state(robot, description, log.motor_pos[0], log.motor_vel[0])
    physics_dt = robot.model.opt.timestep
    gains_logged = log.motor_kp is not None and log.motor_kd is not None
    sim_pos, sim_vel = np.empty_like(log.motor_pos), np.empty_like(log.motor_vel)
    base_pos, base_quat = np.empty((n, 3)), np.empty((n, 4))
    # a step's interval is the logged time to the next step; where the log's clock does not advance (a real
    # robot's first observation is stamped before its clock restarts) the control period stands in
    intervals = np.diff(log.time, append=log.time[-1] + log.control_dt)
    intervals = np.where(intervals > 0, intervals, log.control_dt)
    for k in range(n):
        obs = robot.observe()
        sim_pos[k], sim_vel[k] = obs.motor_pos, obs.motor_vel
        base_pos[k], base_quat[k] = robot.base_pos, robot.base_quat
        robot.n_substeps = max(1, round(float(intervals[k]) / physics_dt))
        kp = log.motor_kp[k] if gains_logged else None
        kd = log.motor_kd[k] if gains_logged else None
        robot.step(log.motor_target[k], kp, kd)
    pos_err = np.degrees(np.abs(sim_pos - log.motor_pos))
    vel_err = np.abs(sim_vel - log.motor_vel)
    motors = [MotorError(name, float(pos_err[:, i].mean()), float(pos_err[:, i].max()), float(vel_err[:, i].mean()))
              for i, name in enumerate(log.motor_names)]
    walking = bool(np.any(np.abs(log.command[:, :2]) > 1e-6) or np.any(np.abs(log.command[:, 2]) > 1e-6))
    sim_tracking = real_tracking = None
    if walking:
        sim_tracking = tracking_errors(log.time, log.command, base_pos, base_quat, fell=robot.fallen)
        if np.all(np.isfinite(log.base_pos)) and np.all(np.isfinite(log.base_quat)):
            real_tracking = tracking_errors(log.time, log.command, log.base_pos, log.base_quat, fell=False)
    return Comparison(motors=motors, position_mae_deg=float(pos_err.mean()), velocity_mae=float(vel_err.mean()),
                      time=np.concatenate([[0.0], np.cumsum(intervals[:-1])]),
                      real_pos=log.motor_pos, sim_pos=sim_pos, sim_tracking=sim_tracking,
                      real_tracking=real_tracking, gains_logged=gains_logged)


def plot_comparison(result: Comparison, folder: str | Path, top: int = 6) -> list[Path]:
    """PNG of the ``top`` motors with the largest position error: logged vs simulated angle over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from toddlerbot.files import save_figure

    order = np.argsort([-e.position_mae_deg for e in result.motors])[:top]
    fig, axes = plt.subplots(len(order), 1, figsize=(9, 1.8 * len(order)), sharex=True, squeeze=False)
    t = result.time - result.time[0]
    for ax, i in zip(axes[:, 0], order, strict=True):
        e = result.motors[i]
        ax.plot(t, np.degrees(result.real_pos[:, i]), lw=1.2, label="logged")
        ax.plot(t, np.degrees(result.sim_pos[:, i]), lw=1.2, ls="--", label="simulated")
        ax.set_ylabel("deg")
        ax.set_title(f"{e.motor}: MAE {e.position_mae_deg:.2f} deg", fontsize=9)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    return [save_figure(fig, Path(folder) / "sim_vs_real.png")]
