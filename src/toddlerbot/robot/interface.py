"""The one robot interface that policies see, identical for the MuJoCo backend and the real robot.

Motor-space arrays are in motor-id order (``Robot.motor_names``); joint-space arrays follow
``Robot.joint_names`` (the transmission map's output joints, one per motor). Gains are Dynamixel firmware
units, so the same numbers drive the simulator and the real motors.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.fall import FALL_TILT_RAD, FallGuard, tilt
from toddlerbot.robot.safety import CommandGuard
from toddlerbot.robot.spec import RobotSpec
from toddlerbot.robot.transmission import TransmissionMap

CONTROL_HZ = 50
"""The control rate, Hz (appendix 8.5, 8.11): the default of every backend, policy, training environment and command
that runs a control loop, the leader arms' publishing rate included."""
CONTROL_DT = 1.0 / CONTROL_HZ
"""The control period, s."""
@dataclass(frozen=True)
class Observation:
    time: float
    """Seconds since reset."""
    motor_pos: np.ndarray
    """Motor angles, rad (n_motors,)."""
    motor_vel: np.ndarray
    """Motor speeds, rad/s (n_motors,)."""
    motor_torque: np.ndarray
    """Motor torque, N*m (simulated) or estimated from present current (hardware) (n_motors,)."""
    joint_pos: np.ndarray
    """Output-joint positions through the transmission map, rad or m (n_motors,)."""
    joint_vel: np.ndarray
    imu_quat: np.ndarray
    """Torso orientation in the world (gravity-aligned) frame, quaternion w, x, y, z."""
    imu_ang_vel: np.ndarray
    """Angular velocity in the IMU frame, rad/s."""
    imu_lin_acc: np.ndarray
    """Specific force in the IMU frame (includes gravity: +9.81 up when at rest), m/s^2."""
    foot_contact: np.ndarray
    """(left, right) booleans; all False where the backend cannot sense contact."""


class GroundTruth(ABC):
    """The capability of knowing the torso's true pose in the world, beyond what the sensors report: simulations
    (`toddlerbot.sim.mujoco_robot.MuJoCoRobot`, the hardware-in-the-loop plant behind the Dynamixel emulator).
    The runner logs it for robots that have it and NaN for the others (the real robot)."""

    @property
    @abstractmethod
    def base_pos(self) -> np.ndarray:
        """Torso (floating base) position in the world, m."""

    @property
    @abstractmethod
    def base_quat(self) -> np.ndarray:
        """Torso orientation in the world, quaternion w, x, y, z."""

    @abstractmethod
    def torso_height(self) -> float:
        """Height of the torso frame above the floor, m."""

    @abstractmethod
    def torso_uprightness(self) -> float:
        """z component of the torso's up axis in the world (1 = upright, 0 = lying)."""

    @property
    @abstractmethod
    def fallen(self) -> bool:
        """The torso tilts beyond its fall threshold or has sunk below a fraction of its standing height."""


class Robot(ABC):
    """A robot a policy can drive: read observations, command motor position targets.

    `step` is the same for every backend: the command passes the shared `CommandGuard` (finite, in range,
    optionally slew-limited) and, while the robot falls, the `FallGuard` (lowered P gains) before the backend's
    `_apply` sees it, so no backend can skip them.
    """

    def __init__(self, description: RobotDescription, control_dt: float, max_step: np.ndarray | None = None) -> None:
        if not control_dt > 0 or not np.isfinite(control_dt):
            raise ValueError(f"control_dt must be a positive number of seconds, got {control_dt}")
        self.description = description
        self.control_dt = control_dt
        self.transmission: TransmissionMap = description.transmission
        self.default_kp = description.default_kp
        self.default_kd = description.default_kd
        self.guard = CommandGuard(
            description.motor_names, description.motor_range, description.joint_range,
            self.transmission.matrix, self.transmission.inverse, max_step,
        )
        self.fall_guard = FallGuard(control_dt)
        self.last_targets: np.ndarray | None = None
        """The last motor targets sent (after the guard), rad; None before `reset`."""
        self.last_gains: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        """The firmware gains (kp, kd) the last step sent, after the guards (None: the backend kept its own)."""

    @property
    def spec(self) -> RobotSpec:
        return self.description.spec

    @property
    def motor_names(self) -> tuple[str, ...]:
        return self.description.motor_names

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.description.joint_names

    @abstractmethod
    def reset(self) -> Observation:
        """Bring the robot to its start state (home pose) and return the first observation."""

    @abstractmethod
    def observe(self) -> Observation:
        """The latest observation, without advancing time."""

    def step(
        self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None
    ) -> Observation:
        """Command motor position targets (rad) with optional per-motor firmware gains, advance one control
        period (control_dt) and return the new observation. Raises `UnsafeCommandError` (nothing sent) for a
        non-finite or malformed command."""
        targets = self.guard.targets(motor_targets, self.last_targets)
        kp = None if kp is None else self.guard.gains(kp, "kp")
        kd = None if kd is None else self.guard.gains(kd, "kd")
        if self.last_targets is None:  # the first step after a reset
            self.fall_guard.reset()
        kp = self.fall_guard.gains(kp, self.default_kp)
        self.last_targets, self.last_gains = targets, (kp, kd)
        obs = self._apply(targets, kp, kd)
        self.fall_guard.update(obs.imu_quat, obs.imu_ang_vel)
        return obs

    @abstractmethod
    def _apply(self, motor_targets: np.ndarray, kp: np.ndarray | None, kd: np.ndarray | None) -> Observation:
        """Send already-checked targets and gains to the backend and advance one control period."""

    @property
    def fallen(self) -> bool:
        """The torso (the IMU's frame: the spec's ``imu`` site is aligned with it) tilts beyond `FALL_TILT_RAD`
        in the latest observation. Backends that know more (the simulator: torso height) refine it."""
        return tilt(self.observe().imu_quat) > FALL_TILT_RAD

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release resources; hardware backends disable torque here."""

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
