"""The emulator under hostile input: malformed packets, bad fault values, the Bus Watchdog, fitted parameters.

These call `EmulatedBus.handle` directly (no pseudo-terminal), so they are fast and deterministic."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from toddlerbot.cli.hw import app
from toddlerbot.hardware import protocol as p
from toddlerbot.hardware.control_table import ENTRIES, encode
from toddlerbot.hardware.emulator import EmulatedBus, Faults, FaultSpecError
from toddlerbot.robot.description import RobotDescription

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

DESC = RobotDescription.load()
BUS = EmulatedBus(DESC)


def _statuses(reply: bytes) -> list[p.Packet]:
    packets = p.PacketParser().feed(reply)
    assert all(isinstance(pk, p.Packet) and pk.instruction == p.STATUS for pk in packets)
    return packets


def _write(bus: EmulatedBus, dxl_id: int, entry: str, value: int) -> int:
    """Error number of the status packet answering a Write."""
    e = ENTRIES[entry]
    (status,) = _statuses(bus.handle(p.Packet(dxl_id, p.WRITE, encode(e.address, 2) + encode(value, e.size))))
    return status.params[0] & 0x7F


def test_fast_sync_read_with_length_0xffff_is_ignored():
    params = encode(132, 2) + encode(0xFFFF, 2) + bytes(range(30))
    assert BUS.handle(p.Packet(p.BROADCAST_ID, p.FAST_SYNC_READ, params)) == b""
    # the bus still answers afterwards
    assert len(_statuses(BUS.handle(p.Packet(3, p.PING, b"")))) == 1


@pytest.mark.parametrize(("instruction", "params", "errors"), [
    (p.SYNC_READ, encode(132, 2) + encode(0xFFFF, 2) + bytes([1, 2]), [p.ERR_ACCESS, p.ERR_ACCESS]),
    (p.SYNC_READ, encode(140, 2) + encode(10, 2) + bytes([1]), [p.ERR_ACCESS]),  # past the end of the table
    (p.FAST_SYNC_READ, encode(0, 2) + encode(0, 2) + bytes([1, 2]), []),
    (p.READ, encode(0xFFFF, 2) + encode(0xFFFF, 2), [p.ERR_ACCESS]),
    (p.READ, b"\x00", [p.ERR_DATA_LENGTH]),
    (p.WRITE, encode(0xFFFF, 2) + b"\x01", [p.ERR_ACCESS]),
    (p.WRITE, b"", [p.ERR_DATA_LENGTH]),
    (p.SYNC_WRITE, encode(116, 2) + encode(0, 2) + bytes([1, 2, 3]), []),
    (p.SYNC_WRITE, encode(116, 2) + encode(0xFFFF, 2) + bytes([1]), []),
    (p.BULK_READ, bytes([1]) + encode(0xFFFF, 2) + encode(0xFFFF, 2), [p.ERR_ACCESS]),
    (0x7F, b"", [p.ERR_INSTRUCTION]),
])
def test_malformed_instructions_are_answered_like_the_firmware(instruction, params, errors):
    dxl_id = 1 if instruction in (p.READ, p.WRITE, 0x7F) else p.BROADCAST_ID
    replies = _statuses(BUS.handle(p.Packet(dxl_id, instruction, params)))
    assert [r.params[0] & 0x7F for r in replies] == errors


@settings(max_examples=150, deadline=None)
@given(dxl_id=st.integers(0, 255), instruction=st.sampled_from(
    [p.PING, p.READ, p.WRITE, p.FACTORY_RESET, p.REBOOT, p.SYNC_READ, p.SYNC_WRITE, p.FAST_SYNC_READ, p.BULK_READ,
     0x00, 0x55, 0xFF]), params=st.binary(max_size=64))
def test_no_packet_can_kill_the_emulator(dxl_id, instruction, params):
    """Whatever arrives, the emulator answers with well-formed status packets (or nothing)."""
    bus = EmulatedBus(DESC)
    reply = bus.handle(p.Packet(dxl_id, instruction, params))
    for status in _statuses(reply):
        assert status.id in {m.id for m in bus.motors}


@pytest.mark.parametrize(("item", "expected"), [
    ("drop=nan", "fault 'drop=nan': a probability must lie in"),
    ("drop=-0.1", "a probability must lie in"),
    ("corrupt=1.5", "a probability must lie in"),
    ("corrupt=inf", "a probability must lie in"),
    ("voltage=nan", r"fault 'voltage=nan': expected a supply voltage in \[0, 30\] V"),
    ("voltage=-1", "expected a supply voltage"),
    ("voltage=inf", "expected a supply voltage"),
    ("missing=300", "motor ids lie in 0..252"),
    ("missing=x", "invalid literal"),
    ("seed=1.5", "invalid literal"),
    ("drop", "expected key=value"),
])
def test_invalid_fault_values_are_refused_in_one_line(item, expected):
    with pytest.raises(FaultSpecError, match=expected) as info:
        Faults.parse([item])
    assert "\n" not in str(info.value)


def test_hw_emulate_refuses_a_nan_voltage_before_serving():
    result = CliRunner().invoke(app, ["emulate", "--faults", "voltage=nan"])
    assert isinstance(result.exception, FaultSpecError) and result.stdout == ""


def test_bus_watchdog_stops_a_motor_that_hears_nothing():
    """Armed (1 unit = 20 ms) with torque on: after 20 ms of silence the motor holds where it is, reads -1 and
    refuses goals with a data range error; torque stays on; writing 0 clears it. Torque off: never fires."""
    bus = EmulatedBus(DESC)
    assert _write(bus, 4, "bus_watchdog", 1) == 0
    time.sleep(0.05)
    bus.check_watchdogs()
    assert bus.motor(4).get("bus_watchdog") == 1  # torque off: the watchdog does not run
    assert _write(bus, 4, "goal_position", 2000) == 0
    assert _write(bus, 4, "torque_enable", 1) == 0
    time.sleep(0.05)
    bus.check_watchdogs()
    motor = bus.motor(4)
    assert motor.get("bus_watchdog") == -1 and motor.torque_on
    assert motor.get("goal_position") == motor.get("present_position")
    assert _write(bus, 4, "goal_position", 2100) == p.ERR_DATA_RANGE
    assert _write(bus, 4, "bus_watchdog", 200) == p.ERR_DATA_RANGE  # 0..127 only
    assert _write(bus, 4, "bus_watchdog", 0) == 0
    assert _write(bus, 4, "goal_position", 2100) == 0 and motor.get("goal_position") == 2100
    assert bus.motor(5).get("bus_watchdog") == 0  # other motors untouched


def test_fitted_motor_params_change_what_the_hil_emulator_simulates(tmp_path):
    """`hw emulate --hil --motor-params` builds the HIL plant from a description with the fitted parameters: the
    MuJoCo model's armature/damping and the actuator model's torque limit both change for that motor model."""
    fitted = {"damping": 0.5, "armature": 0.02, "tau_max": 1.0}
    params = tmp_path / "xm430.json"
    params.write_text(json.dumps({"motor": "XM430-W210", "actuator": fitted}))
    plain = EmulatedBus(DESC, hil=True).plant
    fit = EmulatedBus(RobotDescription.load(motor_params=[params]), hil=True).plant
    xm = [i for i, m in enumerate(DESC.motor_models) if m.name == "XM430-W210"]
    other = [i for i, m in enumerate(DESC.motor_models) if m.name != "XM430-W210"]
    dof = fit.vadr[xm]
    assert fit.model.dof_armature[dof] == pytest.approx(0.02) and fit.model.dof_damping[dof] == pytest.approx(0.5)
    assert not np.allclose(plain.model.dof_armature[dof], 0.02)
    assert [fit.params[i].tau_max for i in xm] == [1.0] * len(xm)
    assert [fit.params[i] for i in other] == [plain.params[i] for i in other]
