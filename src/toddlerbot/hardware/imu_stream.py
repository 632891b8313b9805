"""The hardware-in-the-loop emulator's sensors as a local stream: the simulated IMU, read through the `Imu`
interface, and the torso's true pose, read as motion capture (`StreamMocap`).

`hw emulate --hil` publishes the MuJoCo robot's IMU (the spec's ``imu`` site: orientation, gyro, accelerometer,
in the conventions of `toddlerbot.hardware.imu`) the way the BNO08x delivers it to the robot's computer: a
report every `REPORT_INTERVAL_S` (the interval `Bno08xImu` asks the sensor for), each describing the robot
`LATENCY_S` earlier. `hw run --imu emulator` reads it with `StreamImu`, so a policy sees the emulated robot's
tilt and rates exactly as it would see the real sensor's. Beside it, at the same rate and without the delay, the
publisher sends the torso's world pose to the readers that ask for it (`hw run --mocap emulator`): the ground truth
a motion-capture system would give a real robot, so a run's tracking errors are measured as in the simulator.

Transport: Unix datagram sockets on the same machine. The publisher binds `imu_socket_path(bus_port)` (named
after the emulated bus's pseudo-terminal, so a run finds the sensors of the bus it drives); a reader binds its own
socket, sends `SUBSCRIBE` (the IMU) or `SUBSCRIBE_POSE` and from then on receives fixed-size binary reports (no
pickle): `REPORT`, magic, sequence number, the sample's simulated time (s), quaternion w x y z, gyro (rad/s),
specific force (m/s^2); `POSE_REPORT`, magic, sequence number, simulated time, torso position (m), quaternion w x y z.
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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware.driver import HardwareError
from toddlerbot.hardware.imu import REPORT_INTERVAL_S, Imu, ImuReading

LATENCY_S = 0.005
"""Age of each report when it is delivered, s: the BNO08x fuses a report from the gyro sample just taken, filters
it and raises its interrupt (its datasheet, section 6.8, splits this into sensor, processing, filtering and
transport delays without one figure for the game rotation vector; 5 ms is an assumption, not a measurement)."""
REPORT = struct.Struct("<4sId4d3d3d")
MAGIC = b"TBIM"
SUBSCRIBE = b"subscribe"
POSE_REPORT = struct.Struct("<4sId3d4d")
POSE_MAGIC = b"TBPO"
SUBSCRIBE_POSE = b"subscribe-pose"
FIRST_REPORT_TIMEOUT_S = 1.0
"""How long a reader waits for its first report before saying that no IMU (or pose) is being published."""
STALE_S = 0.25
"""A reader whose newest report is older than this (wall clock, s) reports the IMU lost."""


class ImuStreamError(HardwareError):
    """The emulated IMU (or motion capture) stream is absent or went silent."""


@dataclass(frozen=True)
class Pose:
    """The torso's pose in the world: position (m) and orientation (quaternion w, x, y, z)."""

    pos: np.ndarray
    quat: np.ndarray


def imu_socket_path(bus_port: str) -> Path:
    """The socket the emulator serving ``bus_port`` (e.g. /dev/pts/3) publishes its IMU on."""
    name = bus_port.strip("/").replace("/", "_")
    return Path(tempfile.gettempdir()) / f"toddlerbot-imu-{name}.sock"


def _unpack(data: bytes, report: struct.Struct, magic: bytes) -> tuple[int, float, np.ndarray] | None:
    """(sequence, simulated time, values) of a ``report`` packet; None for anything that is not a finite one."""
    if len(data) != report.size:
        return None
    found, seq, sim_time, *values = report.unpack(data)
    if found != magic or not np.all(np.isfinite(values)):
        return None
    return seq, sim_time, np.asarray(values)


def encode(seq: int, sim_time: float, reading: ImuReading) -> bytes:
    return REPORT.pack(MAGIC, seq & 0xFFFFFFFF, sim_time, *reading.quat, *reading.ang_vel, *reading.lin_acc)


def decode(data: bytes) -> tuple[int, float, ImuReading] | None:
    """(sequence, simulated time, reading) of a report; None for anything that is not one."""
    if (report := _unpack(data, REPORT, MAGIC)) is None:
        return None
    seq, sim_time, v = report
    return seq, sim_time, ImuReading(quat=v[0:4], ang_vel=v[4:7], lin_acc=v[7:10])


def encode_pose(seq: int, sim_time: float, pose: Pose) -> bytes:
    return POSE_REPORT.pack(POSE_MAGIC, seq & 0xFFFFFFFF, sim_time, *pose.pos, *pose.quat)


def decode_pose(data: bytes) -> tuple[int, float, Pose] | None:
    """(sequence, simulated time, pose) of a pose report; None for anything that is not one."""
    if (report := _unpack(data, POSE_REPORT, POSE_MAGIC)) is None:
        return None
    seq, sim_time, v = report
    return seq, sim_time, Pose(pos=v[0:3], quat=v[3:7])


class ImuPublisher:
    """Sends the latest IMU sample, `latency_s` old, to every IMU subscriber every `interval_s` (wall clock), and
    the torso's pose now to every pose subscriber.

    ``sample()`` returns (simulated time, reading) of the robot now; the publisher keeps a short history of them
    (taken at the report rate) and delivers the newest one that is at least `latency_s` old, so a report lags
    the robot as the real sensor's does. ``pose()`` returns (simulated time, torso pose) now; without it (None) a
    pose subscription is ignored."""

    def __init__(self, path: Path, sample: Callable[[], tuple[float, ImuReading]],
                 interval_s: float = REPORT_INTERVAL_S, latency_s: float = LATENCY_S,
                 pose: Callable[[], tuple[float, Pose]] | None = None) -> None:
        self.path, self.sample, self.pose = Path(path), sample, pose
        self.interval_s, self.latency_s = interval_s, latency_s
        self.reports = 0
        self.pose_reports = 0
        self._subscribers: set[str] = set()
        self._pose_subscribers: set[str] = set()
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
            if self._pose_subscribers:
                self._send_pose(*self.pose())
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
            elif data == SUBSCRIBE_POSE and address and self.pose is not None:
                self._pose_subscribers.add(address)

    def _send(self, sim_time: float, reading: ImuReading) -> None:
        self._deliver(encode(self.reports, sim_time, reading), self._subscribers)
        self.reports += 1

    def _send_pose(self, sim_time: float, pose: Pose) -> None:
        self._deliver(encode_pose(self.pose_reports, sim_time, pose), self._pose_subscribers)
        self.pose_reports += 1

    def _deliver(self, packet: bytes, subscribers: set[str]) -> None:
        for address in list(subscribers):
            try:
                self._sock.sendto(packet, address)
            except BlockingIOError:
                pass  # the reader's queue is full (it is not reading yet): it gets the next report
            except (FileNotFoundError, ConnectionRefusedError):
                subscribers.discard(address)  # the reader is gone


class StreamReader:
    """Subscribes to the publisher at ``path`` (``subscribe``: which reports) and keeps its newest report
    (``decode`` of a packet, None for anything else); ``what`` names the stream in errors."""

    def __init__(self, path: Path, subscribe: bytes, decode: Callable[[bytes], tuple | None], size: int, what: str,
                 first_timeout_s: float = FIRST_REPORT_TIMEOUT_S, stale_s: float = STALE_S) -> None:
        self.path, self.first_timeout_s, self.stale_s = Path(path), first_timeout_s, stale_s
        self._decode, self._size, self.what = decode, size, what
        fd, own = tempfile.mkstemp(prefix="toddlerbot-stream-reader-", suffix=".sock")
        os.close(fd)
        os.unlink(own)
        self._own = own
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._sock.bind(own)
        self.latest: tuple | None = None
        self._received_at = 0.0
        try:
            self._sock.sendto(subscribe, str(self.path))
        except (FileNotFoundError, ConnectionRefusedError):
            self.close()
            raise ImuStreamError(f"no emulated {what} at {self.path}: start the emulator with `toddlerbot hw emulate "
                                 "--hil` and pass its port") from None

    def newest(self):
        """The newest report's value (waits up to `first_timeout_s` for the first one)."""
        self._drain(blocking=self.latest is None)
        assert self.latest is not None
        age = time.perf_counter() - self._received_at
        if age > self.stale_s:
            raise ImuStreamError(f"emulated {self.what} {self.path}: no report for {age:.2f} s (the emulator "
                                 "stopped?)")
        return self.latest[2]

    def _drain(self, blocking: bool) -> None:
        self._sock.settimeout(self.first_timeout_s if blocking else 0.0)
        while True:
            try:
                data = self._sock.recv(self._size + 1)
            except (BlockingIOError, InterruptedError):
                return
            except TimeoutError:
                raise ImuStreamError(f"emulated {self.what} {self.path}: no report within "
                                     f"{self.first_timeout_s:g} s") from None
            report = self._decode(data)
            if report is not None and (self.latest is None or report[0] != self.latest[0]):
                self.latest, self._received_at = report, time.perf_counter()
            self._sock.settimeout(0.0)

    def close(self) -> None:
        self._sock.close()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self._own)


class StreamImu(StreamReader, Imu):
    """The `Imu` of an emulated robot: subscribes to the publisher at ``path`` and returns its newest report."""

    def __init__(self, path: Path, first_timeout_s: float = FIRST_REPORT_TIMEOUT_S, stale_s: float = STALE_S) -> None:
        super().__init__(path, SUBSCRIBE, decode, REPORT.size, "IMU", first_timeout_s, stale_s)

    def read(self) -> ImuReading:
        return self.newest()


MOCAP_KINDS = ("none", "emulator")
"""Where `hw run --mocap` reads the torso's true pose from (none: nowhere, the log's pose is NaN)."""


def open_mocap(kind: str, bus_port: str) -> StreamMocap | None:
    """The motion capture of `MOCAP_KINDS` for a robot on ``bus_port`` (None for none)."""
    if kind == "emulator":
        capture = StreamMocap(imu_socket_path(bus_port))
        try:
            capture.read()  # an emulator that publishes no pose (no --hil plant) fails now, before torque is on
        except ImuStreamError:
            capture.close()
            raise
        return capture
    if kind == "none":
        return None
    raise ToddlerbotError(f"--mocap {kind!r}: expected one of {', '.join(MOCAP_KINDS)}")


class StreamMocap(StreamReader):
    """Motion capture of an emulated robot: the torso's true pose, the newest of the publisher's pose reports."""

    def __init__(self, path: Path, first_timeout_s: float = FIRST_REPORT_TIMEOUT_S, stale_s: float = STALE_S) -> None:
        super().__init__(path, SUBSCRIBE_POSE, decode_pose, POSE_REPORT.size, "motion capture", first_timeout_s,
                         stale_s)

    def read(self) -> Pose:
        return self.newest()
