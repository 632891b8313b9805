"""The one robot interface that policies see, identical for the MuJoCo backend and the real robot.

Motor-space arrays are in motor-id order (``Robot.motor_names``); joint-space arrays follow
``Robot.joint_names`` (the transmission map's output joints, one per motor). Gains are Dynamixel firmware
units, so the same numbers drive the simulator and the real motors.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from toddlerbot.robot.spec import RobotSpec
from toddlerbot.robot.transmission import TransmissionMap, build_transmission_map


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


class Robot(ABC):
    """A robot a policy can drive: read observations, command motor position targets."""

    def __init__(self, spec: RobotSpec, control_dt: float) -> None:
        if control_dt <= 0:
            raise ValueError(f"control_dt must be positive, got {control_dt}")
        self.spec = spec
        self.control_dt = control_dt
        self.transmission: TransmissionMap = build_transmission_map(spec)
        self.default_kp = np.array([m.kp for m in spec.motors_by_id], dtype=float)
        self.default_kd = np.array([m.kd for m in spec.motors_by_id], dtype=float)

    @property
    def motor_names(self) -> tuple[str, ...]:
        return self.transmission.motor_names

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.transmission.joint_names

    @abstractmethod
    def reset(self) -> Observation:
        """Bring the robot to its start state (home pose) and return the first observation."""

    @abstractmethod
    def observe(self) -> Observation:
        """The latest observation, without advancing time."""

    @abstractmethod
    def step(
        self, motor_targets: np.ndarray, kp: np.ndarray | None = None, kd: np.ndarray | None = None
    ) -> Observation:
        """Command motor position targets (rad) with optional per-motor firmware gains, advance one control
        period (control_dt) and return the new observation."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release resources; hardware backends disable torque here."""

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
