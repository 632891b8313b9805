"""What a manipulation task is: a scene on the gripper robot, reset for a seed, stepped at the task's gains, with a
success check, a head camera, a progress report for runs and (optionally) a scripted demonstrator."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING

import numpy as np

from toddlerbot.robot.interface import Observation
from toddlerbot.runtime.runner import RunObserver, Step
from toddlerbot.tasks.camera import HeadCamera
from toddlerbot.tasks.space import ManipulationSpace

if TYPE_CHECKING:
    from toddlerbot.policies.base import Policy
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot


class Task(ABC):
    """A task of the `TASKS` registry. Subclasses set the attributes below in their constructor (which takes an
    optional `RobotDescription`) and implement `reset`, `step` and `succeeded`."""

    name: str
    instruction: str
    """The language instruction recorded with its episodes."""
    episode_seconds: float
    """How long an episode may last, s (`dp eval`'s default limit)."""
    description: RobotDescription
    robot: MuJoCoRobot
    """The simulated robot in the task's scene."""
    space: ManipulationSpace
    """The motors its episodes record."""
    kp: np.ndarray
    """Firmware gains the task steps at when a policy sends none."""
    camera: HeadCamera

    @abstractmethod
    def reset(self, seed: int) -> Observation:
        """The scene and robot in their start state for `seed`; the first observation."""

    @abstractmethod
    def step(self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None
             ) -> Observation:
        """One control step through the robot's guard, at the task's gains unless given; updates success."""

    @property
    @abstractmethod
    def succeeded(self) -> bool:
        """Whether the episode has succeeded (it stays so once it has)."""

    def head_image(self) -> np.ndarray:
        """The head camera's 96x96 RGB image (uint8) of the current state."""
        return self.camera.image()

    def progress(self) -> RunObserver:
        """A run observer reporting how the episode went (`sim run --task`): by default, success and when."""
        return TaskProgress(self)

    def demonstrator(self) -> Policy:
        """The task's scripted demonstrator (`manip demo`); a task without one says so in one line."""
        from toddlerbot.errors import ToddlerbotError

        raise ToddlerbotError(f"task {self.name!r} has no scripted demonstrator; record it by teleoperation")


class TaskProgress(RunObserver):
    """A run observer: whether the task succeeded, and when first."""

    def __init__(self, task: Task) -> None:
        self.task = task
        self.succeeded_at: float | None = None

    def on_step(self, step: Step) -> None:
        if self.succeeded_at is None and self.task.succeeded:
            self.succeeded_at = step.next_obs.time

    @property
    def succeeded(self) -> bool:
        return self.succeeded_at is not None

    def to_dict(self) -> dict:
        return {"name": self.task.name, "succeeded": self.succeeded, "succeeded_at_s": self.succeeded_at}

    def describe(self) -> str:
        ended = "not succeeded" if self.succeeded_at is None else f"succeeded at {self.succeeded_at:.2f} s"
        return f"{self.task.name}: {ended}"
