"""The IMU behind a small interface: a BNO08x on I2C (optional at install time) or a stand-in.

Readings use the simulated IMU's conventions (`toddlerbot.robot.interface.Observation`): orientation of the
torso in a gravity-aligned world frame as a quaternion (w, x, y, z), angular velocity (rad/s) and specific
force (m/s^2, +9.81 up at rest) in the IMU frame. `mount_quat` rotates the sensor's axes into the frame of the
spec's ``imu`` site.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from toddlerbot.errors import ToddlerbotError

GRAVITY = 9.81
REPORT_INTERVAL_S = 0.01
"""Interval `Bno08xImu` asks the sensor to report at, s (100 Hz). The Adafruit driver's default is 50 ms (20 Hz):
with the IMU held for 50 ms, walk-zmp falls after 3.0 s of the tracking schedule in the simulator, while with 10 ms
it walks it as with a fresh reading every control step (docs/hardware.md, "IMU")."""


@dataclass(frozen=True)
class ImuReading:
    quat: np.ndarray
    """w, x, y, z"""
    ang_vel: np.ndarray
    """rad/s, IMU frame"""
    lin_acc: np.ndarray
    """m/s^2, IMU frame (specific force)"""


class Imu(ABC):
    @abstractmethod
    def read(self) -> ImuReading: ...

    def close(self) -> None:  # noqa: B027 - optional hook
        pass


class StaticImu(Imu):
    """An upright robot at rest: for benches without an IMU and the hardware-in-the-loop emulator."""

    def read(self) -> ImuReading:
        return ImuReading(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), np.array([0.0, 0.0, GRAVITY]))


class Bno08xImu(Imu):
    """BNO08x (BNO080/085/086) over I2C via the Adafruit CircuitPython driver.

    Reports, each every `REPORT_INTERVAL_S`: game rotation vector (gravity-aligned, heading relative to
    power-up), calibrated gyroscope and accelerometer. Pass `device` (anything with ``game_quaternion``,
    ``gyro``, ``acceleration``) to use an already opened sensor; otherwise the sensor at `address` on the
    board's default I2C bus is opened.
    """

    def __init__(self, address: int = 0x4A, mount_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
                 device: object | None = None) -> None:
        w, x, y, z = mount_quat
        self._mount = Rotation.from_quat([x, y, z, w])
        self.device = device if device is not None else self._open(address)

    @staticmethod
    def _open(address: int) -> object:
        try:
            import board
            import busio
            from adafruit_bno08x import (
                BNO_REPORT_ACCELEROMETER,
                BNO_REPORT_GAME_ROTATION_VECTOR,
                BNO_REPORT_GYROSCOPE,
            )
            from adafruit_bno08x.i2c import BNO08X_I2C
        except ImportError:
            raise ToddlerbotError(
                "the BNO08x IMU needs adafruit-circuitpython-bno08x >= 1.3 (pip install 'toddlerbot[imu]')"
            ) from None
        try:
            sensor = BNO08X_I2C(busio.I2C(board.SCL, board.SDA, frequency=400_000), address=address)
            for report in (BNO_REPORT_GAME_ROTATION_VECTOR, BNO_REPORT_GYROSCOPE, BNO_REPORT_ACCELEROMETER):
                sensor.enable_feature(report, report_interval=round(REPORT_INTERVAL_S * 1e6))
        except (OSError, RuntimeError, ValueError) as exc:
            raise ToddlerbotError(f"BNO08x at I2C address 0x{address:02x}: {exc}") from None
        return sensor

    def read(self) -> ImuReading:
        i, j, k, real = self.device.game_quaternion  # the driver's order: x, y, z, w
        orientation = Rotation.from_quat([i, j, k, real]) * self._mount.inv()
        x, y, z, w = orientation.as_quat()
        to_site = self._mount
        return ImuReading(
            quat=np.array([w, x, y, z]) * (1 if w >= 0 else -1),
            ang_vel=to_site.apply(np.asarray(self.device.gyro, dtype=float)),
            lin_acc=to_site.apply(np.asarray(self.device.acceleration, dtype=float)),
        )
