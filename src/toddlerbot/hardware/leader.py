"""The leader arm pair: its own Dynamixel bus, torque off, read at the control rate (appendix 8.12).

The operator moves the leader arms by hand; `LeaderArms.read` returns their calibrated motor angles (rad) in
the order of the motors it was built with (the follower's arm and gripper motors). The bus is the project's
`DynamixelBus` (retries, one Sync Read per cycle); a failed read raises its `BusError`, which the teleoperation
loop turns into "leader lost: holding the last safe targets".
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from toddlerbot.hardware.control_table import pulses_to_rad
from toddlerbot.hardware.driver import DynamixelBus, motors_of
from toddlerbot.robot.description import RobotDescription

LEADER_GROUPS = ("arm", "gripper")


@dataclass(frozen=True)
class LeaderReading:
    time: float
    """time.monotonic() when the read completed, s."""
    positions: np.ndarray
    """Calibrated motor angles, rad, in `LeaderArms.names` order."""


class LeaderArms:
    """Reads the leader arms (same motor ids and names as the follower's arm and gripper motors)."""

    def __init__(self, description: RobotDescription, port: str, offsets: dict[str, int], baudrate: int = 2_000_000,
                 retries: int = 3) -> None:
        ids = {m.id for m in description.motors if m.group in LEADER_GROUPS}
        motors = motors_of(description, ids)
        missing = [m.name for m in motors if m.name not in offsets]
        if missing:
            raise ValueError(f"leader calibration has no zero offset for {', '.join(missing)}")
        self.names = tuple(m.name for m in motors)
        self.offsets = np.array([offsets[n] for n in self.names], dtype=np.int64)
        self.bus = DynamixelBus(port, motors, baudrate=baudrate, retries=retries)

    def open(self) -> LeaderArms:
        """Open the port, check the motors answer, and make sure torque is off (the arms move freely)."""
        self.bus.open()
        self.bus.scan()
        self.bus.disable_torque()
        return self

    def read(self) -> LeaderReading:
        """One Sync Read of all leader motors (raises `BusError` after the bus's retries)."""
        state = self.bus.read_state()
        raw = pulses_to_rad(state.position - self.offsets)
        return LeaderReading(time.monotonic(), (raw + np.pi) % (2 * np.pi) - np.pi)

    def close(self) -> None:
        self.bus.close()

    def __enter__(self) -> LeaderArms:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

