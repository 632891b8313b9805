"""Scripted pick demonstrator, a `Policy` done after `DemoConfig.duration`: end-effector waypoints solved by
damped-least-squares IK every control step.

Phases (times in s from the episode start, `DemoConfig`): ``approach`` to a pre-grasp point above the cube,
``descend`` onto it, ``close`` the gripper, ``lift``, ``hold``. The grasp point (midway between the finger pads)
follows minimum-jerk segments between waypoints, pointing down with the fingers closing across two cube faces.
The pre-grasp waypoint is perturbed per episode (`waypoint_noise`). The low-gain arm sags under gravity, so the
targets lead the IK solution by the gravity torque over the motor stiffness (what an operator does without
thinking), and a slow task-space integral term removes what is left: the recorded actions differ from the
follower's angles as they do in teleoperated data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import mujoco
import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.tasks.ik import (
    CORRECTION_GAIN,
    MAX_CORRECTION,
    ArmIK,
    GraspPointCorrection,
    IKConfig,
    top_down_rotation,
)
from toddlerbot.tasks.scenes import grasp_site


class PickScene(Protocol):
    """What the picker needs of its task (`toddlerbot.tasks.pick.PickTask`): the arm, gains and poses, the cube."""

    description: RobotDescription
    model: mujoco.MjModel
    robot: MuJoCoRobot
    kp: np.ndarray
    gripper_motor: int
    ready_pose: np.ndarray
    seed: int | None

    @property
    def arm(self) -> str: ...

    def gripper_range(self) -> tuple[float, float]: ...

    def cube_pose(self) -> tuple[np.ndarray, np.ndarray]: ...

PHASES = ("approach", "descend", "close", "lift", "hold")


@dataclass(frozen=True)
class DemoConfig:
    approach_s: float = 1.2
    descend_s: float = 1.5
    close_s: float = 0.6
    lift_s: float = 1.0
    hold_s: float = 1.5
    pregrasp_height: float = 0.05
    """Pre-grasp point above the cube centre, m."""
    lift_height: float = 0.06
    """How far the grasp point rises in the lift phase, m."""
    grasp_depth: float = 0.0
    """Grasp point below the cube centre, m (pads centred slightly low)."""
    waypoint_noise: float = 0.008
    """Standard deviation of the pre-grasp waypoint's offset, m."""
    correction_gain: float = CORRECTION_GAIN
    max_correction: float = MAX_CORRECTION
    grip_fraction: float = 0.75
    """Gripper target when closed, as a fraction of the drive's range: the pads meet a 3 cm cube at 0.38 of it;
    squeezing to the very end lets the (compliant) rack run far past contact and can pop the cube out."""

    @property
    def duration(self) -> float:
        return self.approach_s + self.descend_s + self.close_s + self.lift_s + self.hold_s


def min_jerk(s: float) -> float:
    # Not locomotion.swing.min_jerk: s**2 there is s*s, which differs in the last bit for a fifth of the inputs,
    # and the chaotic grasps the demonstrations and their measured figures come from are this one's.
    s = min(max(s, 0.0), 1.0)
    return s**3 * (10 - 15 * s + 6 * s**2)


class ScriptedPicker(Policy):
    """Drives the pick task (through its `TaskRobot`) from its observations, one control step at a time, at the
    task's gains; the waypoint noise comes from the seed the task was reset with."""

    name = "scripted-pick"

    def __init__(self, task: PickScene, config: DemoConfig | None = None) -> None:
        super().__init__(task.robot)
        self.task = task
        self.config = config or DemoConfig()
        self._steps = round(self.config.duration / self.control_dt)
        self._step = 0
        side = task.arm
        self.ik = ArmIK(task.description, task.model, side, IKConfig(), site=grasp_site(side))
        self.open, fully_closed = task.gripper_range()
        self.closed = self.open + self.config.grip_fraction * (fully_closed - self.open)
        self._stiffness = task.description.actuator_arrays(task.kp).kp[self.ik.arm]
        """Physical position gains of the arm motors at the follower's gains, N*m/rad."""
        self._targets = task.ready_pose.copy()
        self._correction = GraspPointCorrection(self.config.correction_gain, self.config.max_correction)
        self._waypoints: list[np.ndarray] = []
        self._rotation = np.eye(3)

    @property
    def duration(self) -> float:
        """Length of an episode, s."""
        return self.config.duration

    @property
    def done(self) -> bool:
        return self._step >= self._steps

    def reset(self, task_obs: Observation) -> None:
        """Plan the episode's waypoints from the cube's pose (right after `PickTask.reset`: the run loop's reset of
        the `TaskRobot`)."""
        cfg = self.config
        rng = np.random.default_rng(self.task.seed)
        cube_pos, cube_rot = self.task.cube_pose()
        start, _ = self.ik.forward(task_obs.motor_pos, self.task.robot.data.qpos)
        # Close across the pair of cube faces whose normal is nearest the gripper's current closing axis.
        faces = [cube_rot[:, 0], cube_rot[:, 1]]
        current = self.ik.forward(task_obs.motor_pos, self.task.robot.data.qpos)[1][:, 2]
        face = max(faces, key=lambda n: abs(float(n[:2] @ current[:2])))
        self._rotation = top_down_rotation(face if face[:2] @ current[:2] >= 0 else -face)
        noise = np.clip(rng.normal(0.0, cfg.waypoint_noise, 3), -2.5 * cfg.waypoint_noise, 2.5 * cfg.waypoint_noise)
        grasp = cube_pos - np.array([0.0, 0.0, cfg.grasp_depth])
        pregrasp = grasp + np.array([0.0, 0.0, cfg.pregrasp_height]) + noise
        lifted = grasp + np.array([0.0, 0.0, cfg.lift_height])
        self._waypoints = [start, pregrasp, grasp, grasp, lifted, lifted]
        self._targets = task_obs.motor_pos.copy()
        self._targets[self.task.gripper_motor] = self.open
        self._correction = GraspPointCorrection(cfg.correction_gain, cfg.max_correction)
        self._step = 0

    def phase(self, t: float) -> str:
        cfg = self.config
        edges = np.cumsum([cfg.approach_s, cfg.descend_s, cfg.close_s, cfg.lift_s])
        return PHASES[int(np.searchsorted(edges, t, side="right"))]

    def desired_grasp_point(self, t: float) -> np.ndarray:
        cfg = self.config
        durations = [cfg.approach_s, cfg.descend_s, cfg.close_s, cfg.lift_s, cfg.hold_s]
        for i, duration in enumerate(durations):
            if t < duration or i == len(durations) - 1:
                a, b = self._waypoints[i], self._waypoints[i + 1]
                return a + (b - a) * min_jerk(t / duration)
            t -= duration
        raise AssertionError("unreachable")

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        """Motor targets (rad, all motors) for the next control step, at the task's gains."""
        cfg = self.config
        t = obs.time
        desired = self.desired_grasp_point(t)
        measured, _ = self.ik.forward(obs.motor_pos, self.task.robot.data.qpos)
        base = self.task.robot.data.qpos
        q, _ = self.ik.solve(self._targets, self._correction.target(desired, measured), self._rotation, base)
        self._targets = q.copy()
        q[self.ik.arm] += self.ik.gravity_torque(q, base) / self._stiffness
        phase = self.phase(t)
        if phase == "close":
            s = min_jerk((t - cfg.approach_s - cfg.descend_s) / cfg.close_s)
            q[self.task.gripper_motor] = self.open + s * (self.closed - self.open)
        elif phase in ("lift", "hold"):
            q[self.task.gripper_motor] = self.closed
        else:
            q[self.task.gripper_motor] = self.open
        self._targets[self.task.gripper_motor] = q[self.task.gripper_motor]
        self._step += 1
        return Action(q, self.transmission.motor_to_joint(q), kp=self.task.kp)
