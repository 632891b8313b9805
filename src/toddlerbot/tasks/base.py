"""What a manipulation task is, as one registration (`toddlerbot.tasks.TASKS`) carries it: its scene (what it adds
to the gripper robot's MjSpec), a reset for a seed, a step at the task's gains, a success check, a head camera, a
progress report for runs, (optionally) a scripted demonstrator, the robot teleoperation drives in it and the start
a skill chain in its scene runs from. `TaskRobot` makes a task's episode a `Robot` for the run loop."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.runtime.runner import RunObserver, Step
from toddlerbot.sim.ground_truth import TorsoGroundTruth
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.tasks.camera import HeadCamera
from toddlerbot.tasks.space import ManipulationSpace


@dataclass(frozen=True)
class StartPerturbation:
    """How far a chain's start is off the task's start for its seed, to measure a chain's margin."""

    pose_offset: float = 0.0
    """Each motor starts up to this far off the start pose (uniform, drawn from the seed), rad."""
    object_shift: tuple[float, float] = (0.0, 0.0)
    """Added to the seed's shift of the scene's object where the task shifts one (the wagon), (x, y) m."""

    def motor_offset(self, rng: np.random.Generator, n_motors: int) -> np.ndarray:
        """The motors' start offsets, rad, drawn from the seed's generator."""
        return rng.uniform(-1, 1, n_motors) * self.pose_offset


class Task(ABC):
    """A task of the `TASKS` registry. Subclasses set the attributes below in their constructor (which takes an
    optional `RobotDescription`) and implement `add_scene`, `reset`, `step`, `succeeded` and `chain_start`."""

    mounted: ClassVar[bool] = False
    """Whether the scene holds the torso in place (at a table): then no walking policy drives the robot."""
    variations: ClassVar[tuple[str, ...]] = ("default",)
    """Named scene variations its constructor takes as ``variation`` (`make_task("NAME:VARIATION")`)."""

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

    @staticmethod
    @abstractmethod
    def add_scene(mj: mujoco.MjSpec, description: RobotDescription, home: np.ndarray) -> np.ndarray:
        """Add the task's objects (and constraints) to the gripper robot's MjSpec, whose home keyframe is `home`;
        return the home positions of the joints added, in order (`toddlerbot.tasks.scenes.scene_model`)."""

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

    def failure_kind(self) -> str:
        """What a failed episode ended in, for `dp eval`'s report: by default, no more than that."""
        return "not succeeded"

    def head_image(self) -> np.ndarray:
        """The head camera's 96x96 RGB image (uint8) of the current state."""
        return self.camera.image()

    def progress(self) -> RunObserver:
        """A run observer reporting how the episode went (`sim run --task`): by default, success and when."""
        return TaskProgress(self)

    def demonstrator(self) -> Policy:
        """The task's scripted demonstrator (`manip demo`); a task without one says so in one line."""
        raise ToddlerbotError(f"task {self.name!r} has no scripted demonstrator; record it by teleoperation")

    def teleop_robot(self, seed: int) -> Robot:
        """The robot teleoperation drives in the task's scene (`teleop --task`): by default the task's episode for
        `seed`, at the task's gains."""
        return TaskRobot(self, seed)

    @abstractmethod
    def chain_start(self, seed: int, perturbation: StartPerturbation) -> tuple[Robot, np.ndarray]:
        """(robot, start motor targets) of a skill chain run in the task's scene (`chain run` in sim), which the
        run loop's reset puts at the seed's start."""


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


class TaskRobot(Robot, TorsoGroundTruth):
    """A task episode's robot for the run loop: `reset` is the task's reset for ``seed``, `step` is the task's step
    (its gains unless ``kp`` is given; success tracked). The task's simulated robot is `sim`; ground truth and the
    scene (`model`, `data`, for rendering and probes) are its own."""

    def __init__(self, task: Task, seed: int) -> None:
        super().__init__(task.description, task.robot.control_dt)
        self.task, self.seed, self.sim = task, seed, task.robot
        self.torso_truth = task.robot.torso_truth
        self.default_kp = task.kp  # what the task steps at when a policy sends no gains

    @property
    def model(self) -> mujoco.MjModel:
        return self.sim.model

    @property
    def data(self) -> mujoco.MjData:
        return self.sim.data

    def reset(self) -> Observation:
        obs = self.task.reset(self.seed)
        self.last_targets = self.sim.last_targets
        return obs

    def observe(self) -> Observation:
        return self.sim.observe()

    def step(self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None
             ) -> Observation:
        """The task's step; the simulator's own `step` guards the command (a second guard here would clamp twice,
        and clamping through a coupled transmission is not exactly idempotent)."""
        obs = self.task.step(motor_targets, kp, kd)
        self.last_targets, self.last_gains = self.sim.last_targets, self.sim.last_gains
        return obs

    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        raise NotImplementedError("a TaskRobot steps through its task's `step`")

    @property
    def fallen(self) -> bool:
        return self.sim.fallen
