"""The emulator's IMU stream: binary reports at the BNO08x rate, each as old as the sensor's latency, read through
the `Imu` interface; a missing or silent stream is one clear error."""

import time

import numpy as np
import pytest

from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware.imu import REPORT_INTERVAL_S, ImuReading
from toddlerbot.hardware.imu_stream import (
    POSE_REPORT,
    REPORT,
    ImuPublisher,
    ImuStreamError,
    Pose,
    StreamImu,
    StreamMocap,
    decode,
    decode_pose,
    encode,
    encode_pose,
    imu_socket_path,
    open_mocap,
)

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)


def _reading(t: float) -> ImuReading:
    return ImuReading(quat=np.array([1.0, 0.0, 0.0, t]), ang_vel=np.array([t, 0.0, 0.0]), lin_acc=np.zeros(3))


def test_reports_round_trip_and_anything_else_is_ignored():
    packet = encode(7, 1.25, _reading(0.5))
    assert len(packet) == REPORT.size == 96
    seq, sim_time, reading = decode(packet)
    assert (seq, sim_time) == (7, 1.25) and reading.quat[3] == 0.5 and reading.ang_vel[0] == 0.5
    assert decode(packet[:-1]) is None and decode(b"XXXX" + packet[4:]) is None
    assert decode(encode(1, 0.0, ImuReading(np.full(4, np.nan), np.zeros(3), np.zeros(3)))) is None


def test_pose_reports_round_trip_and_are_not_imu_reports():
    packet = encode_pose(3, 2.5, Pose(pos=np.array([0.1, -0.2, 0.3]), quat=np.array([0.0, 0.0, 0.0, 1.0])))
    assert len(packet) == POSE_REPORT.size == 72
    seq, sim_time, pose = decode_pose(packet)
    assert (seq, sim_time) == (3, 2.5) and pose.pos.tolist() == [0.1, -0.2, 0.3] and pose.quat[3] == 1.0
    assert decode(packet) is None and decode_pose(encode(1, 0.0, _reading(0.0))) is None
    assert decode_pose(b"XXXX" + packet[4:]) is None


def test_the_socket_is_named_after_the_bus_port():
    assert imu_socket_path("/dev/pts/3").name == "toddlerbot-imu-dev_pts_3.sock"
    assert imu_socket_path("/dev/pts/3") != imu_socket_path("/dev/pts/4")


def test_reader_gets_reports_at_the_report_rate_each_as_old_as_the_latency(tmp_path):
    clock = time.perf_counter
    publisher = ImuPublisher(tmp_path / "imu.sock", lambda: (clock(), _reading(clock())), latency_s=0.02).start()
    try:
        imu = StreamImu(tmp_path / "imu.sock")
        ages, sequences, times = [], [], []
        for _ in range(40):
            reading = imu.read()
            times.append(clock())
            ages.append(times[-1] - reading.ang_vel[0])  # the sample's wall time travels in the reading
            sequences.append(imu.latest[0])
            time.sleep(REPORT_INTERVAL_S / 2)
        imu.close()
    finally:
        publisher.stop()
    assert 0.02 <= np.median(ages) < 0.02 + 3 * REPORT_INTERVAL_S  # latency + up to a report interval
    rate = (sequences[-1] - sequences[0]) / (times[-1] - times[0])
    assert 0.5 / REPORT_INTERVAL_S < rate <= 1.1 / REPORT_INTERVAL_S  # ~100 reports/s (fewer on a loaded host)
    assert not (tmp_path / "imu.sock").exists()  # the publisher removes its socket


def test_no_emulator_and_a_silent_one_are_one_line_errors(tmp_path):
    with pytest.raises(ImuStreamError, match=r"no emulated IMU at .*imu\.sock: start the emulator"):
        StreamImu(tmp_path / "imu.sock")
    publisher = ImuPublisher(tmp_path / "imu.sock", lambda: (0.0, _reading(0.0))).start()
    imu = StreamImu(tmp_path / "imu.sock", stale_s=0.1)
    imu.read()
    publisher.stop()
    time.sleep(0.2)
    with pytest.raises(ImuStreamError, match=r"no report for 0\.\d\d s \(the emulator stopped\?\)"):
        imu.read()
    imu.close()


def _pose(t: float) -> Pose:
    return Pose(pos=np.array([t, 0.0, 0.3]), quat=np.array([1.0, 0.0, 0.0, 0.0]))


def test_motion_capture_readers_get_the_pose_now_and_imu_readers_the_imu(tmp_path):
    clock = time.perf_counter
    publisher = ImuPublisher(tmp_path / "imu.sock", lambda: (clock(), _reading(clock())), latency_s=0.02,
                             pose=lambda: (clock(), _pose(clock()))).start()
    try:
        mocap, imu = StreamMocap(tmp_path / "imu.sock"), StreamImu(tmp_path / "imu.sock")
        ages = []
        for _ in range(20):
            pose, reading = mocap.read(), imu.read()
            ages.append((clock() - pose.pos[0], clock() - reading.ang_vel[0]))
            time.sleep(REPORT_INTERVAL_S / 2)
        mocap.close()
        imu.close()
    finally:
        publisher.stop()
    pose_age, imu_age = np.median(ages, axis=0)
    assert pose_age < 0.02 <= imu_age  # the pose is not delayed as the IMU's reports are
    assert publisher.pose_reports > 5 and publisher.reports > 5


def test_motion_capture_from_nowhere_is_a_one_line_error_before_torque(tmp_path):
    assert open_mocap("none", "/dev/pts/99") is None
    with pytest.raises(ToddlerbotError, match=r"^--mocap 'optitrack': expected one of none, emulator$"):
        open_mocap("optitrack", "/dev/pts/99")
    with pytest.raises(ImuStreamError, match=r"no emulated motion capture at .*: start the emulator with"):
        open_mocap("emulator", "/dev/pts/99")
    # an emulator with an IMU but no body to track (no --hil plant) publishes no pose
    port = "/dev/pts/98"
    publisher = ImuPublisher(imu_socket_path(port), lambda: (0.0, _reading(0.0))).start()
    try:
        with pytest.raises(ImuStreamError, match=r"^emulated motion capture .*: no report within 1 s$"):
            open_mocap("emulator", port)
    finally:
        publisher.stop()
