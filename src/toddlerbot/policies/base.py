"""The `Policy` interface: observation (+ velocity command) -> motor targets, at the robot's control rate."""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from toddlerbot.locomotion.config import CommandReach
from toddlerbot.robot.interface import Observation, Robot

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Action:
    motor_targets: np.ndarray
    """Motor position targets, rad (n_motors,) in motor-id order."""
    joint_targets: np.ndarray
    """The same targets in joint space (for logging), rad or m."""
    kp: np.ndarray | None = None
    """Firmware position gains (Dynamixel units); None keeps the spec's."""
    kd: np.ndarray | None = None


class Policy(ABC):
    """A controller the runner calls once per control period."""

    name: str = "policy"
    command_reach: CommandReach | None = None
    """The velocity commands the policy follows (None: it ignores commands); `within_reach` clamps to it."""
    needs_imu: bool = False
    """True for a policy that balances from the IMU: the hardware commands refuse it without one."""
    demo_command: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """What `sim run` follows without ``--command`` (vx m/s, vy m/s, yaw rate rad/s): a walk to look at for a policy
    that shows one by default, standing still otherwise."""

    def __init__(self, robot: Robot) -> None:
        self._warned_reach = False
        self.robot = robot
        self.transmission = robot.transmission
        self.control_dt = robot.control_dt
        self.home_joint_pos = robot.description.home_joint_pos
        """Output-joint positions of the home pose (read-only; copy before changing)."""

    @abstractmethod
    def reset(self, obs: Observation) -> None:
        """Start over from the given observation."""

    @abstractmethod
    def act(self, obs: Observation, command: np.ndarray) -> Action:
        """Targets for the next control period; command = (vx m/s, vy m/s, yaw rate rad/s) in the robot frame."""

    def within_reach(self, command: np.ndarray) -> np.ndarray:
        """The command clamped to `command_reach`; the first clamp of a run logs one warning."""
        command = np.asarray(command, dtype=float)
        if self.command_reach is None:
            return command
        clamped = self.command_reach.clamp(command)
        if not self._warned_reach and not np.array_equal(clamped, command):
            self._warned_reach = True
            log.warning("%s: command (%s) is beyond its reach (%s); clamped to (%s)", self.name,
                        ", ".join(f"{v:g}" for v in command), self.command_reach.describe(),
                        ", ".join(f"{v:g}" for v in clamped))
        return clamped

    @property
    def done(self) -> bool:
        """True once a finite behaviour (a motion replay) has finished."""
        return False

    @property
    def status(self) -> object | None:
        """What the policy reports about itself during or after a run (a diffusion policy's inference statistics,
        a chain's phases), an object with ``to_dict()`` (JSON) and ``describe()`` (one line for people); None when it
        has nothing to say."""
        return None

    def close(self) -> None:  # noqa: B027 (most policies hold nothing to release)
        """Release what the policy holds (worker threads, sessions); the run loop calls it on every exit path,
        and calling it twice is harmless."""

    def joint_action(self, joint_targets: np.ndarray) -> Action:
        """An action from joint-space targets (converted to motor space through the transmissions)."""
        joint_targets = np.asarray(joint_targets, dtype=float)
        return Action(motor_targets=self.transmission.joint_to_motor(joint_targets), joint_targets=joint_targets)
