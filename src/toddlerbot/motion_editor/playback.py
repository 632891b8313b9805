"""Play a motion in the MuJoCo simulator exactly as `toddlerbot sim run --policy replay` does (same robot, policy,
runner and fall detector; the actuator model every 1 ms), keeping every control step's state for the page.

A motion whose first keyframe gives a base pose (a get-up motion) starts there, resting on the floor, and plays to
its end: it starts down, so the fall detector does not stop it; the result says whether it ended standing."""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.motion_editor.balance import Balance, PoseModel
from toddlerbot.policies.motions import Motion, full_pose
from toddlerbot.policies.replay import ReplayPolicy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.floor_pose import place_on_floor
from toddlerbot.runtime.runner import RunObserver, Step, run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimulationError


@dataclass(frozen=True)
class Playback:
    times: np.ndarray
    """(n,) simulated time of each frame, s (one frame per control step, 20 ms)."""
    qpos: np.ndarray
    """(n, nq) MuJoCo configuration of each frame."""
    balance: tuple[Balance, ...]
    """CoM and contact support polygon of each frame."""
    fall_time: float | None
    """s, when the fall detector fired (the run stops there), or None."""
    error: str | None
    """Why the simulation stopped early (it diverged), or None."""
    max_tilt_deg: float
    """Largest torso tilt from upright, deg."""
    min_height_m: float
    """Lowest torso height, m."""
    compute_s: float
    """Wall-clock time the simulation took, s."""
    from_lying: bool = False
    """The motion started lying (its first keyframe's base pose); then `upright` is whether it ended standing."""
    final_uprightness: float = 1.0
    """z component of the torso's up axis at the end (1 = upright)."""

    @property
    def upright(self) -> bool:
        if self.from_lying:
            return self.error is None and self.final_uprightness >= STOOD_UPRIGHTNESS
        return self.fall_time is None and self.error is None

    def describe(self) -> str:
        duration = self.times[-1] if len(self.times) else 0.0
        head = (f"stopped: {self.error}" if self.error else
                f"{'stood up' if self.upright else 'ended down'} (uprightness {self.final_uprightness:.2f})"
                if self.from_lying else
                f"FELL at {self.fall_time:.2f} s" if self.fall_time is not None else "stayed upright")
        return (f"{head}: {duration:.2f} s simulated in {self.compute_s:.1f} s; max tilt {self.max_tilt_deg:.1f} deg, "
                f"lowest torso {self.min_height_m * 1000:.0f} mm")


STOOD_UPRIGHTNESS = 0.9
"""A motion that started lying ended standing when the torso's up axis has at least this z component."""


def simulate(description: RobotDescription, motion: Motion) -> Playback:
    """Run `motion` on the floating robot until it ends or the robot falls, from the home pose, or from its first
    keyframe lying on the floor when that keyframe gives a base pose (then to its end, falls or not)."""
    started = time.perf_counter()
    robot = MuJoCoRobot(description)
    lying = motion.start_base
    if lying is not None:
        robot.start_qpos = place_on_floor(robot.model, mujoco.MjData(robot.model), description.transmission,
                                          full_pose(motion, description), lying.roll, lying.pitch,
                                          lying.z).qpos.copy()
    policy = ReplayPolicy(robot, motion)
    trace = _Trace(robot, PoseModel(description), robot.model.body(description.handles.torso).id)
    fall_time, error = None, None
    try:
        result = run_policy(robot, policy, seconds=motion.duration + 1.0, observers=[trace],
                            stop_on_fall=lying is None)
        fall_time = result.fall_time
    except SimulationError as exc:
        error = str(exc)
    times, qpos, balance, tilt, height = trace.times, trace.qpos, trace.balance, trace.tilt, trace.height
    return Playback(np.array(times), np.array(qpos).reshape(len(qpos), -1), tuple(balance), fall_time, error,
                    max(tilt, default=0.0), min(height, default=0.0), time.perf_counter() - started,
                    from_lying=lying is not None, final_uprightness=robot.torso_uprightness())


class _Trace(RunObserver):
    """The playback's per-step record: time, pose, contact balance, torso tilt and height."""

    def __init__(self, robot: MuJoCoRobot, poses: PoseModel, torso: int) -> None:
        self.robot, self.poses, self.torso = robot, poses, torso
        self.times, self.qpos, self.balance, self.tilt, self.height = [], [], [], [], []

    def on_step(self, step: Step) -> None:
        d = self.robot.data
        self.times.append(float(d.time))
        self.qpos.append(d.qpos.copy())
        self.balance.append(self.poses.contact_balance(d))
        self.tilt.append(float(np.degrees(np.arccos(np.clip(d.xmat[self.torso, 8], -1.0, 1.0)))))
        self.height.append(float(d.xpos[self.torso, 2]))
