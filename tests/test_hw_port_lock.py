"""One process per serial port: a second opener is refused (naming the holder's PID) before it sends a byte, the
holder keeps working, and the port is free again once the holder closes it, is stopped or is killed."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial

from hw_support import emulated
from toddlerbot.hardware.driver import DynamixelBus, motors_of
from toddlerbot.hardware.port_lock import PortInUseError
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import load_spec

pytestmark = pytest.mark.realtime  # emulator in wall-clock time: runs alone (conftest.py)

DESC = RobotDescription(load_spec())
SRC = Path(__file__).resolve().parents[1] / "src"
ENV = {**os.environ, "PYTHONPATH": str(SRC)}
HOLDER = """
import sys, time
from toddlerbot.hardware.driver import DynamixelBus, motors_of
from toddlerbot.robot.description import RobotDescription
with DynamixelBus(sys.argv[1], motors_of(RobotDescription.load())) as bus:
    print(len(bus.scan()), flush=True)
    if len(sys.argv) > 2:
        time.sleep(float(sys.argv[2]))
"""
"""A child process that opens the bus, prints how many motors answered, and holds the port argv[2] s."""


def _holder(path: str, hold_s: float | None = None, **kwargs) -> subprocess.Popen:
    args = [sys.executable, "-c", HOLDER, path] + ([] if hold_s is None else [str(hold_s)])
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV, **kwargs)


def test_a_second_process_is_refused_before_sending_while_the_first_keeps_working():
    with emulated(DESC) as (emu, path), DynamixelBus(path, motors_of(DESC)) as bus:
        assert len(bus.scan()) == 30
        sent, answered = emu.stats.bytes_in, emu.stats.bytes_out
        result = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", "hw", "scan", "--port", path],
                                capture_output=True, text=True, timeout=60, env=ENV)
        assert result.returncode == 2 and "Traceback" not in result.stderr
        assert result.stderr.strip().count("\n") == 0  # one line
        assert f"{path} is in use by process {os.getpid()} (" in result.stderr
        assert "stop it first" in " ".join(result.stderr.split())
        assert (emu.stats.bytes_in, emu.stats.bytes_out) == (sent, answered)  # not one byte reached the bus
        state = bus.read_state()  # the holder's port still works
        assert list(state.position) == [m.get("present_position") for m in emu.motors]
        assert emu.stats.bytes_in > sent
    with emulated(DESC) as (emu, path):
        first = DynamixelBus(path, motors_of(DESC)).open()
        first.close()
        child = _holder(path)  # a closed port is free for the next process
        out, err = child.communicate(timeout=30)
        assert child.returncode == 0, err
        assert out.split() == ["30"]


def test_the_same_device_under_another_name_or_opened_by_pyserial_is_refused(tmp_path):
    with emulated(DESC) as (emu, path), DynamixelBus(path, motors_of(DESC)):
        alias = tmp_path / "by-id-u2d2"
        alias.symlink_to(path)
        with pytest.raises(PortInUseError, match=f"^{alias} is in use by process {os.getpid()} "):
            DynamixelBus(str(alias), motors_of(DESC)).open()
        with pytest.raises(serial.SerialException, match="exclusively lock"):
            serial.Serial(path, exclusive=True)  # pyserial's own exclusive mode takes the same lock
        assert emu.stats.bytes_in == 0


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_or_killed_holder_leaves_the_port_free(stop):
    with emulated(DESC) as (emu, path):
        child = _holder(path, hold_s=60)
        assert child.stdout.readline().split() == ["30"]
        sent = emu.stats.bytes_in
        with pytest.raises(PortInUseError, match=f"^{path} is in use by process {child.pid} \\(python"):
            DynamixelBus(path, motors_of(DESC)).open()
        assert emu.stats.bytes_in == sent
        child.send_signal(stop)
        child.wait(timeout=10)
        start = time.perf_counter()
        with DynamixelBus(path, motors_of(DESC)) as bus:  # no stale lock: the kernel released it
            assert len(bus.scan()) == 30
        assert time.perf_counter() - start < 5.0
    assert child.returncode == -stop if stop == signal.SIGKILL else child.returncode != 0
