"""The hardware-in-the-loop emulator's simulated IMU as a local stream, read through the `Imu` interface.

`hw emulate --hil` publishes the MuJoCo robot's IMU (the spec's ``imu`` site: orientation, gyro, accelerometer,
in the conventions of `toddlerbot.hardware.imu`) the way the BNO08x delivers it to the robot's computer: a
report every `REPORT_INTERVAL_S` (the interval `Bno08xImu` asks the sensor for), each describing the robot
`LATENCY_S` earlier. `hw run --imu emulator` reads it with `StreamImu`, so a policy sees the emulated robot's
tilt and rates exactly as it would see the real sensor's.

Transport: Unix datagram sockets on the same machine. The publisher binds `imu_socket_path(bus_port)` (named
after the emulated bus's pseudo-terminal, so a run finds the IMU of the bus it drives); a reader binds its own
socket, sends `SUBSCRIBE` and from then on receives fixed-size binary reports (`REPORT`, no pickle):
magic, sequence number, the sample's simulated time (s), quaternion w x y z, gyro (rad/s), specific force (m/s^2).
"""

from __future__ import annotations

import collections
import contextlib
import os
import socket
import struct
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from toddlerbot.hardware.driver import HardwareError
from toddlerbot.hardware.imu import REPORT_INTERVAL_S, Imu, ImuReading

LATENCY_S = 0.005
"""Age of each report when it is delivered, s: the BNO08x fuses a report from the gyro sample just taken, filters
it and raises its interrupt (its datasheet, section 6.8, splits this into sensor, processing, filtering and
transport delays without one figure for the game rotation vector; 5 ms is an assumption, not a measurement)."""
REPORT = struct.Struct("<4sId4d3d3d")
MAGIC = b"TBIM"
SUBSCRIBE = b"subscribe"
FIRST_REPORT_TIMEOUT_S = 1.0
"""How long a reader waits for its first report before saying that no IMU is being published."""
STALE_S = 0.25
"""A reader whose newest report is older than this (wall clock, s) reports the IMU lost."""


class ImuStreamError(HardwareError):
    """The emulated IMU stream is absent or went silent."""


def imu_socket_path(bus_port: str) -> Path:
    """The socket the emulator serving ``bus_port`` (e.g. /dev/pts/3) publishes its IMU on."""
    name = bus_port.strip("/").replace("/", "_")
    return Path(tempfile.gettempdir()) / f"toddlerbot-imu-{name}.sock"


def encode(seq: int, sim_time: float, reading: ImuReading) -> bytes:
    return REPORT.pack(MAGIC, seq & 0xFFFFFFFF, sim_time, *reading.quat, *reading.ang_vel, *reading.lin_acc)


def decode(data: bytes) -> tuple[int, float, ImuReading] | None:
    """(sequence, simulated time, reading) of a report; None for anything that is not one."""
    if len(data) != REPORT.size:
        return None
    magic, seq, sim_time, *values = REPORT.unpack(data)
    if magic != MAGIC or not np.all(np.isfinite(values)):
        return None
    v = np.asarray(values)
    return seq, sim_time, ImuReading(quat=v[0:4], ang_vel=v[4:7], lin_acc=v[7:10])


class ImuPublisher:
    """Sends the latest IMU sample, `latency_s` old, to every subscriber every `interval_s` (wall clock).

    ``sample()`` returns (simulated time, reading) of the robot now; the publisher keeps a short history of them
    (taken at the report rate) and delivers the newest one that is at least `latency_s` old, so a report lags
    the robot as the real sensor's does."""

    def __init__(self, path: Path, sample: Callable[[], tuple[float, ImuReading]],
                 interval_s: float = REPORT_INTERVAL_S, latency_s: float = LATENCY_S) -> None:
        self.path, self.sample = Path(path), sample
        self.interval_s, self.latency_s = interval_s, latency_s
        self.reports = 0
        self._subscribers: set[str] = set()
        self._history: collections.deque[tuple[float, float, ImuReading]] = collections.deque()
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()  # a socket left behind by an emulator that was killed
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._sock.bind(str(self.path))
        self._sock.setblocking(False)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="imu-publisher", daemon=True)

    def start(self) -> ImuPublisher:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)
        self._sock.close()
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()

    def _run(self) -> None:
        next_tick = time.perf_counter()
        while not self._stop.is_set():
            self._accept_subscribers()
            now = time.perf_counter()
            self._history.append((now, *self.sample()))
            cutoff = now - self.latency_s + 1e-4
            while len(self._history) > 1 and self._history[1][0] <= cutoff:
                self._history.popleft()  # the oldest left is the newest sample that is old enough
            if self._history[0][0] <= cutoff:
                self._send(*self._history[0][1:])
            next_tick += self.interval_s
            self._stop.wait(max(0.0, next_tick - time.perf_counter()))
            if time.perf_counter() - next_tick > self.interval_s:
                next_tick = time.perf_counter()  # fell behind (a loaded host): do not burst to catch up

    def _accept_subscribers(self) -> None:
        while True:
            try:
                data, address = self._sock.recvfrom(64)
            except (BlockingIOError, InterruptedError):
                return
            if data == SUBSCRIBE and address:
                self._subscribers.add(address)

    def _send(self, sim_time: float, reading: ImuReading) -> None:
        packet = encode(self.reports, sim_time, reading)
        self.reports += 1
        for address in list(self._subscribers):
            try:
                self._sock.sendto(packet, address)
            except BlockingIOError:
                pass  # the reader's queue is full (it is not reading yet): it gets the next report
            except (FileNotFoundError, ConnectionRefusedError):
                self._subscribers.discard(address)  # the reader is gone


class StreamImu(Imu):
    """The `Imu` of an emulated robot: subscribes to the publisher at ``path`` and returns its newest report."""

    def __init__(self, path: Path, first_timeout_s: float = FIRST_REPORT_TIMEOUT_S, stale_s: float = STALE_S) -> None:
        self.path, self.first_timeout_s, self.stale_s = Path(path), first_timeout_s, stale_s
        fd, own = tempfile.mkstemp(prefix="toddlerbot-imu-reader-", suffix=".sock")
        os.close(fd)
        os.unlink(own)
        self._own = own
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._sock.bind(own)
        self.latest: tuple[int, float, ImuReading] | None = None
        self._received_at = 0.0
        try:
            self._sock.sendto(SUBSCRIBE, str(self.path))
        except (FileNotFoundError, ConnectionRefusedError):
            self.close()
            raise ImuStreamError(f"no emulated IMU at {self.path}: start the emulator with `toddlerbot hw emulate "
                                 "--hil` and pass its port") from None

    def read(self) -> ImuReading:
        self._drain(blocking=self.latest is None)
        assert self.latest is not None
        age = time.perf_counter() - self._received_at
        if age > self.stale_s:
            raise ImuStreamError(f"emulated IMU {self.path}: no report for {age:.2f} s (the emulator stopped?)")
        return self.latest[2]

    def _drain(self, blocking: bool) -> None:
        self._sock.settimeout(self.first_timeout_s if blocking else 0.0)
        while True:
            try:
                data = self._sock.recv(REPORT.size + 1)
            except (BlockingIOError, InterruptedError):
                return
            except TimeoutError:
                raise ImuStreamError(f"emulated IMU {self.path}: no report within {self.first_timeout_s:g} s") from None
            report = decode(data)
            if report is not None and (self.latest is None or report[0] != self.latest[0]):
                self.latest, self._received_at = report, time.perf_counter()
            self._sock.settimeout(0.0)

    def close(self) -> None:
        self._sock.close()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self._own)
