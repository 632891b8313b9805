"""The driver against the emulator: setup, control cycle, retries, bad input, and torque left off."""

import os
import signal
import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from hw_support import emulated
from toddlerbot.hardware import protocol as p
from toddlerbot.hardware.control_table import (
    MODE_CURRENT_BASED_POSITION,
    MODE_EXTENDED_POSITION,
    RAD_PER_PULSE,
    STATE_BLOCK,
)
from toddlerbot.hardware.driver import BusError, DynamixelBus, HardwareError, motors_of
from toddlerbot.hardware.emulator import Faults
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import load_spec

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

SPEC = load_spec()
DESC = RobotDescription(SPEC)


def test_configure_and_control_cycle_tracks_goals():
    with emulated(SPEC) as (emu, path), DynamixelBus(path, motors_of(DESC)) as bus:
        assert bus.scan()[7] == 1030
        bus.configure()
        assert bus.fast_sync_read
        knee = emu.motor(7)
        assert knee.get("operating_mode") == MODE_EXTENDED_POSITION and knee.get("return_delay_time") == 0
        assert (knee.get("position_p_gain"), knee.get("position_d_gain")) == (2700, 160)
        start = bus.read_state().position
        bus.enable_torque()
        assert all(m.torque_on for m in emu.motors)
        goal = start + np.round(0.3 / RAD_PER_PULSE).astype(np.int64)  # every motor +0.3 rad
        for _ in range(60):
            bus.write_goal_positions(goal)
            state = bus.read_state()
            time.sleep(0.005)
        assert np.abs(state.position - goal).max() * RAD_PER_PULSE < 0.05
        assert bus.bytes_tx > 0 and bus.bytes_rx > 0
    assert not any(m.torque_on for m in emu.motors)  # closing the bus disabled torque


def test_gripper_variant_uses_current_based_position_mode():
    spec = SPEC.with_variant("gripper")
    with emulated(spec) as (emu, path), DynamixelBus(path, motors_of(RobotDescription(spec))) as bus:
        bus.scan()
        bus.configure()
        assert emu.motor(30).get("operating_mode") == MODE_CURRENT_BASED_POSITION
        assert emu.motor(30).get("goal_current") == 300  # 0.3 A in 1 mA units


def test_falls_back_to_sync_read_without_fast_sync_read():
    with emulated(SPEC, fast_sync_read=False) as (emu, path), DynamixelBus(path, motors_of(DESC)) as bus:
        bus.scan()
        bus.configure()
        assert not bus.fast_sync_read
        state = bus.read_state()
        assert list(state.position) == [m.get("present_position") for m in emu.motors]


def test_retries_recover_from_dropped_and_corrupted_packets():
    faults = Faults(drop=0.01, corrupt=0.02, seed=11)  # per status packet; 30 motors share a fast sync read
    with emulated(SPEC, faults) as (emu, path), DynamixelBus(path, motors_of(DESC), retries=8) as bus:
        bus.scan()
        for _ in range(20):
            state = bus.read_state()
        assert list(state.position) == [m.get("present_position") for m in emu.motors]
    assert emu.stats.packets_in > 20


def test_nonexistent_port_is_named():
    with pytest.raises(HardwareError, match="/dev/ttyNOPE"):
        DynamixelBus("/dev/ttyNOPE", motors_of(DESC)).open()


def test_missing_motor_is_named_and_torque_stays_off():
    with emulated(SPEC, Faults(missing=frozenset({9}))) as (emu, path):
        bus = DynamixelBus(path, motors_of(DESC), retries=2)
        with pytest.raises(BusError, match=r"motor 9 \(left_ankle_pitch, XM430-W210\) does not answer"), bus:
            bus.scan()
        bus = DynamixelBus(path, motors_of(DESC), retries=2)
        with pytest.raises(BusError, match=r"no state answer from motor 9 \(left_ankle_pitch"), bus:
            bus.read_state()
        bus = DynamixelBus(path, motors_of(DESC), retries=2)
        with pytest.raises(BusError, match=r"motor 9 \(left_ankle_pitch, XM430-W210\): read .* no status packet"), bus:
            bus.enable_torque()
        assert not any(m.torque_on for m in emu.motors)


def test_wrong_model_number_is_named():
    spec = load_spec()
    motors = motors_of(RobotDescription(spec))
    motors[7], motors[8] = motors[8].__class__(**{**motors[8].__dict__, "id": 7}), motors[7]
    expected = r"motor 7 \(left_ankle_roll, XC430-T240BB\): reports model number 1030 \(XM430-W210\), expected 1080"
    with emulated(spec) as (_, path), DynamixelBus(path, motors[:8]) as bus, pytest.raises(BusError, match=expected):
        bus.scan()


def test_low_supply_voltage_refuses_torque():
    with emulated(SPEC, Faults(voltage=10.0)) as (emu, path), DynamixelBus(path, motors_of(DESC)) as bus:
        bus.scan()
        with pytest.raises(BusError, match=r"supply voltage too low: .* reads 10.0 V, need at least 10.5 V"):
            bus.enable_torque()
        assert not any(m.torque_on for m in emu.motors)


def test_overload_is_reported_with_the_motor_and_torque_goes_off():
    with emulated(SPEC, Faults(overload=frozenset({13}))) as (emu, path):
        bus = DynamixelBus(path, motors_of(DESC))
        with pytest.raises(BusError, match=r"motor 13 \(right_knee_drive, XM430-W210\).*hardware error: overload"), bus:
            bus.scan()
            bus.configure()
        assert not any(m.torque_on for m in emu.motors)


def test_an_exception_inside_the_with_block_disables_torque():
    with emulated(SPEC) as (emu, path):
        with pytest.raises(ZeroDivisionError), DynamixelBus(path, motors_of(DESC)) as bus:
            bus.scan()
            bus.configure()
            bus.enable_torque()
            assert all(m.torque_on for m in emu.motors)
            _ = 1 / 0
        assert not any(m.torque_on for m in emu.motors)


class _GarbagePeer:
    """A pty whose far end answers every packet with attacker-chosen bytes."""

    def __init__(self) -> None:
        import tty

        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.reply = b""
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        import select

        parser = p.PacketParser()
        while not self.stop.is_set():
            ready = select.select([self.master], [], [], 0.02)[0]
            if ready and parser.feed(os.read(self.master, 4096)) and self.reply:
                os.write(self.master, self.reply)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=2)
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture(scope="module")
def garbage_peer():
    peer = _GarbagePeer()
    yield peer
    peer.close()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@example(reply=p.build_status(3, 0, bytes(STATE_BLOCK[1])))  # a valid state answer: found by CI
@given(reply=st.one_of(
    st.binary(max_size=300),
    st.builds(lambda body, i: (p.build_status(3, 0, body)[:i]), st.binary(max_size=20), st.integers(0, 40)),
    st.builds(lambda body: p.build_status(5, 0, body), st.binary(max_size=20)),
))
def test_garbage_answers_never_hang_the_driver(garbage_peer, reply):
    """Whatever comes back (noise, truncated, foreign or accidentally well-formed status packets), every call
    returns or raises BusError (never another exception) within a bounded time (retries x SDK timeout); the scan
    never succeeds on these answers, and the state read only on a well-formed status from motor 3 that carries
    exactly the state block (a valid answer)."""
    garbage_peer.reply = reply
    motors = motors_of(DESC, {3})
    bus = DynamixelBus(garbage_peer.path, motors, retries=2)
    bus.open()
    try:
        start = time.perf_counter()
        with pytest.raises(BusError):
            bus.scan()
        try:
            state = bus.read_state()
            assert reply.startswith(p.HEADER + bytes([3])) and len(reply) == 11 + STATE_BLOCK[1]
            assert np.isfinite(state.velocity).all() and np.isfinite(state.torque).all()
        except BusError:
            pass
        try:
            value = bus.read(motors[0], "present_position")
            assert reply.startswith(p.HEADER + bytes([3])) and -(2**31) <= value < 2**31
        except BusError:
            pass
        assert time.perf_counter() - start < 5.0
    finally:
        bus.close()


def test_sigterm_disables_torque():
    with emulated(SPEC) as (emu, path):
        with pytest.raises(KeyboardInterrupt), DynamixelBus(path, motors_of(DESC)) as bus:
            bus.scan()
            bus.enable_torque()
            assert all(m.torque_on for m in emu.motors)
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1.0)  # the handler raises KeyboardInterrupt here
        assert not any(m.torque_on for m in emu.motors)
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_cli_reports_a_missing_port_in_one_line():
    import subprocess
    import sys
    from pathlib import Path

    src = Path(__file__).resolve().parents[1] / "src"
    result = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", "hw", "scan", "--port", "/dev/ttyNOPE"],
                            capture_output=True, text=True, timeout=60, env={**os.environ, "PYTHONPATH": str(src)})
    assert result.returncode == 2
    assert "cannot open serial port /dev/ttyNOPE" in " ".join(result.stderr.split())
    assert "Traceback" not in result.stderr


def test_a_signal_during_close_is_raised_only_after_torque_is_off():
    """A second Ctrl-C (here SIGTERM) while closing must not cut the torque-off short."""
    from toddlerbot.hardware.driver import BusInterrupt

    with emulated(SPEC) as (emu, path):
        bus = DynamixelBus(path, motors_of(DESC)).open()
        bus.scan()
        bus.enable_torque()
        original = bus._torque_off_until

        def interrupted(*args):
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.2)  # the handler runs here: it must only record the signal
            return original(*args)

        bus._torque_off_until = interrupted
        with pytest.raises(BusInterrupt, match="SIGTERM"):
            bus.close()
        assert not any(m.torque_on for m in emu.motors) and not bus.is_open
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_a_host_stall_longer_than_the_bus_watchdog_stops_the_run():
    """The motors held by their watchdog ignore goals, so the driver must not carry on: the next state read
    names the stopped motors; torque still goes off at close."""
    with emulated(SPEC) as (emu, path), DynamixelBus(path, motors_of(DESC), watchdog_s=0.1) as bus:
        bus.scan()
        bus.configure()
        bus.enable_torque()
        assert {m.get("bus_watchdog") for m in emu.motors} == {5}  # 0.1 s in 20 ms units, armed after torque-on
        bus.read_state()
        time.sleep(0.4)
        with pytest.raises(BusError, match=r"host was silent for 0\.\d+ s, longer than the 0.1 s Bus Watchdog; "
                                           r"stopped motors: motor 0 \(neck_yaw_drive"):
            bus.read_state()
    assert not any(m.torque_on for m in emu.motors)
