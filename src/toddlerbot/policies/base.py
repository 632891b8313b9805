"""The `Policy` interface: observation (+ velocity command) -> motor targets, at the robot's control rate."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from toddlerbot.robot.interface import Observation, Robot


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

    def __init__(self, robot: Robot) -> None:
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

    @property
    def done(self) -> bool:
        """True once a finite behaviour (a motion replay) has finished."""
        return False

    def joint_action(self, joint_targets: np.ndarray) -> Action:
        """An action from joint-space targets (converted to motor space through the transmissions)."""
        joint_targets = np.asarray(joint_targets, dtype=float)
        return Action(motor_targets=self.transmission.joint_to_motor(joint_targets), joint_targets=joint_targets)
