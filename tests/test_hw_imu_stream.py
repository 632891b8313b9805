"""The emulator's IMU stream: binary reports at the BNO08x rate, each as old as the sensor's latency, read through
the `Imu` interface; a missing or silent stream is one clear error."""

import time

import numpy as np
import pytest

from toddlerbot.hardware.imu import REPORT_INTERVAL_S, ImuReading
from toddlerbot.hardware.imu_stream import (
    REPORT,
    ImuPublisher,
    ImuStreamError,
    StreamImu,
    decode,
    encode,
    imu_socket_path,
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
