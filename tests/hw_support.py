"""Shared helpers of the hardware tests: an in-process emulator on a pty and the official SDK as its peer."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from toddlerbot.hardware.emulator import EmulatedBus, Faults, PtyServer
from toddlerbot.hardware.imu import StaticImu
from toddlerbot.hardware.imu_stream import ImuPublisher, imu_socket_path
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import RobotSpec

sdk = pytest.importorskip("dynamixel_sdk")
port_handler = pytest.importorskip("dynamixel_sdk.port_handler")


@contextmanager
def emulated(
    robot: RobotDescription | RobotSpec | None = None, faults: Faults | None = None, **kwargs
) -> Iterator[tuple[EmulatedBus, str]]:
    """An emulated bus served from a thread; yields (bus, device path)."""
    with emulated_server(robot, faults, **kwargs) as server:
        yield server.bus, server.path


@contextmanager
def emulated_server(
    robot: RobotDescription | RobotSpec | None = None, faults: Faults | None = None, **kwargs
) -> Iterator[PtyServer]:
    """`emulated`, yielding the server itself (its `stop()` closes the pty: the bus is lost, as when a U2D2 is
    unplugged).

    The SDK busy-waits for status packets while holding the GIL; a short switch interval lets the emulator
    thread answer promptly (the CLI emulator runs in its own process and needs no such thing). The SDK's status
    timeout (2 x latency timer + 2 ms) is raised from 34 to about 100 ms so that a loaded CI machine does not
    turn scheduling delays into spurious timeouts."""
    old = sys.getswitchinterval()
    old_latency = port_handler.LATENCY_TIMER
    sys.setswitchinterval(0.0002)
    port_handler.LATENCY_TIMER = 50
    if not isinstance(robot, RobotDescription):
        robot = RobotDescription.load() if robot is None else RobotDescription(robot)
    server = PtyServer(EmulatedBus(robot, faults=faults, **kwargs)).start()
    try:
        yield server
    finally:
        server.stop()
        sys.setswitchinterval(old)
        port_handler.LATENCY_TIMER = old_latency


@contextmanager
def sdk_port(path: str, baudrate: int = 2_000_000) -> Iterator[object]:
    port = sdk.PortHandler(path)
    assert port.openPort() and port.setBaudRate(baudrate)
    try:
        yield port
    finally:
        port.closePort()


@contextmanager
def upright_imu_stream(port: str) -> Iterator[None]:
    """An IMU stream for `hw run --imu emulator` on an emulated bus without a simulated body (the simple plant):
    an upright robot at rest."""
    publisher = ImuPublisher(imu_socket_path(port), lambda: (0.0, StaticImu().read())).start()
    try:
        yield
    finally:
        publisher.stop()
