"""The IMUs a robot command reads (`--imu`), by name: the robot's BNO08x, the hardware-in-the-loop emulator's
simulated IMU (found from the emulator's bus port), or none (an upright, still stand-in: only for policies that do
not balance)."""

from __future__ import annotations

from collections.abc import Callable

from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware.imu import Bno08xImu, Imu, StaticImu
from toddlerbot.hardware.imu_stream import StreamImu, imu_socket_path

IMU_KINDS: dict[str, Callable[[str], Imu]] = {
    "bno08x": lambda bus_port: Bno08xImu(),
    "emulator": lambda bus_port: StreamImu(imu_socket_path(bus_port)),
    "none": lambda bus_port: StaticImu(),
}
"""`--imu` name -> the IMU of a robot on a bus port."""


def open_imu(kind: str, bus_port: str) -> Imu:
    """The IMU `kind` names for a robot on ``bus_port``; one line naming the kinds for another name."""
    if kind not in IMU_KINDS:
        raise ToddlerbotError(f"--imu {kind!r}: expected one of {', '.join(IMU_KINDS)}")
    return IMU_KINDS[kind](bus_port)
