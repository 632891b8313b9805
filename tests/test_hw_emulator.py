"""The emulator, with the official dynamixel_sdk client as its peer over a pseudo-terminal."""

import pytest

from hw_support import emulated, sdk, sdk_port
from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.hardware import protocol as p
from toddlerbot.hardware.control_table import ENTRIES
from toddlerbot.hardware.emulator import Faults, FaultSpecError
from toddlerbot.robot.spec import load_spec

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

SPEC = load_spec()
PH = sdk.PacketHandler(2.0)
OK = sdk.COMM_SUCCESS


def test_ping_returns_each_motors_catalogue_model_number():
    catalogue = default_catalogue()
    with emulated(SPEC) as (_, path), sdk_port(path) as port:
        for motor in SPEC.motors_by_id:
            number, comm, error = PH.ping(port, motor.id)
            assert (comm, error) == (OK, 0)
            assert number == catalogue[motor.model].model_number
        assert PH.ping(port, 77)[1] == sdk.COMM_RX_TIMEOUT  # nobody has id 77
        found, comm = PH.broadcastPing(port)
        assert comm == OK and sorted(found) == list(range(30)) and found[7][0] == 1030


def test_read_write_and_eeprom_lock():
    with emulated(SPEC) as (bus, path), sdk_port(path) as port:
        assert PH.write1ByteTxRx(port, 9, ENTRIES["operating_mode"].address, 4) == (OK, 0)
        assert PH.read1ByteTxRx(port, 9, ENTRIES["operating_mode"].address) == (4, OK, 0)
        assert PH.write2ByteTxRx(port, 9, ENTRIES["position_p_gain"].address, 2700) == (OK, 0)
        assert PH.read2ByteTxRx(port, 9, ENTRIES["position_p_gain"].address) == (2700, OK, 0)
        assert PH.write1ByteTxRx(port, 9, ENTRIES["torque_enable"].address, 1) == (OK, 0)
        # EEPROM (operating mode) is locked while torque is on: access error, value unchanged
        assert PH.write1ByteTxRx(port, 9, ENTRIES["operating_mode"].address, 3) == (OK, p.ERR_ACCESS)
        assert bus.motor(9).get("operating_mode") == 4
        # read-only entry, invalid operating mode for a model without current sensing, out-of-range gain
        assert PH.write2ByteTxRx(port, 9, ENTRIES["model_number"].address, 1)[1] == p.ERR_ACCESS
        assert PH.write1ByteTxRx(port, 9, ENTRIES["torque_enable"].address, 0) == (OK, 0)
        assert PH.write1ByteTxRx(port, 8, ENTRIES["operating_mode"].address, 5) == (OK, p.ERR_DATA_RANGE)  # XC430
        assert PH.write1ByteTxRx(port, 0, ENTRIES["operating_mode"].address, 5) == (OK, 0)  # XC330 senses current
        assert PH.write2ByteTxRx(port, 9, ENTRIES["position_p_gain"].address, 20000)[1] == p.ERR_DATA_RANGE


def test_sync_read_fast_sync_read_and_sync_write_agree():
    ids = [3, 7, 16, 29]
    with emulated(SPEC) as (bus, path), sdk_port(path) as port:
        writer = sdk.GroupSyncWrite(port, PH, ENTRIES["position_p_gain"].address, 2)
        for i in ids:
            writer.addParam(i, [i, 0x10])  # 0x1000 + id
        assert writer.txPacket() == OK
        PH.ping(port, ids[0])  # a round trip: the emulator has handled the (unanswered) sync write
        assert [bus.motor(i).get("position_p_gain") for i in ids] == [0x1000 + i for i in ids]
        reader = sdk.GroupSyncRead(port, PH, ENTRIES["position_p_gain"].address, 2)
        for i in ids:
            reader.addParam(i)
        assert reader.txRxPacket() == OK
        assert [reader.getData(i, 84, 2) for i in ids] == [0x1000 + i for i in ids]
        assert reader.fastSyncRead() == OK
        assert [reader.getData(i, 84, 2) for i in ids] == [0x1000 + i for i in ids]
        position = sdk.GroupSyncRead(port, PH, ENTRIES["present_position"].address, 4)
        for i in ids:
            position.addParam(i)
        assert position.fastSyncRead() == OK
        assert [position.getData(i, 132, 4) for i in ids] == [bus.motor(i).get("present_position") for i in ids]


def test_bulk_read_reboot_and_factory_reset():
    with emulated(SPEC) as (bus, path), sdk_port(path) as port:
        bulk = sdk.GroupBulkRead(port, PH)
        assert bulk.addParam(7, ENTRIES["model_number"].address, 2)
        assert bulk.addParam(12, ENTRIES["present_input_voltage"].address, 2)
        assert bulk.txRxPacket() == OK
        assert bulk.getData(7, 0, 2) == 1030 and bulk.getData(12, 144, 2) == 120
        PH.write1ByteTxRx(port, 5, ENTRIES["torque_enable"].address, 1)
        PH.write1ByteTxRx(port, 5, ENTRIES["return_delay_time"].address, 0)  # refused: torque on
        assert PH.reboot(port, 5) == (OK, 0)
        assert not bus.motor(5).torque_on and 0 <= bus.motor(5).get("present_position") < 4096
        PH.write1ByteTxRx(port, 5, ENTRIES["return_delay_time"].address, 0)
        assert bus.motor(5).get("return_delay_time") == 0
        assert PH.factoryReset(port, 5, 0x01) == (OK, 0)  # all but the id
        assert bus.motor(5).get("return_delay_time") == 250 and bus.motor(5).id == 5


def test_unknown_instruction_gets_an_instruction_error():
    with emulated(SPEC) as (_, path), sdk_port(path) as port:
        _, comm, error = PH.txRxPacket(port, [0, 0, 0, 0, 4, 3, 0, 0x77, 0, 0])
        assert (comm, error) == (OK, p.ERR_INSTRUCTION)


def test_faults_missing_id_low_voltage_and_overload():
    faults = Faults(missing=frozenset({4}), voltage=9.0, overload=frozenset({13}))
    with emulated(SPEC, faults) as (_, path), sdk_port(path) as port:
        assert PH.ping(port, 4)[1] == sdk.COMM_RX_TIMEOUT
        voltage, comm, error = PH.read2ByteTxRx(port, 7, ENTRIES["present_input_voltage"].address)
        assert (voltage, comm) == (90, OK)
        assert error & p.ALERT  # 9.0 V is below the XM430's 9.5 V minimum: input-voltage alert
        assert PH.read1ByteTxRx(port, 7, ENTRIES["hardware_error_status"].address)[0] & 0x01
        assert PH.read1ByteTxRx(port, 0, ENTRIES["hardware_error_status"].address)[2] == 0  # XC330: fine down to 5.5 V
        assert PH.write1ByteTxRx(port, 13, ENTRIES["torque_enable"].address, 1)[1] & p.ALERT
        assert PH.read1ByteTxRx(port, 13, ENTRIES["torque_enable"].address)[0] == 0  # overload keeps torque off
        assert PH.read1ByteTxRx(port, 13, ENTRIES["hardware_error_status"].address)[0] == 0x21  # overload + voltage


def test_dropped_and_corrupted_packets():
    with emulated(SPEC, Faults(drop=0.3, corrupt=0.3, seed=3)) as (_, path), sdk_port(path) as port:
        results = [PH.ping(port, 7)[1] for _ in range(60)]
    assert results.count(OK) > 10
    assert results.count(sdk.COMM_RX_TIMEOUT) > 5  # dropped
    assert results.count(sdk.COMM_RX_CORRUPT) > 5  # corrupted CRC


def test_fault_strings_parse_and_bad_ones_are_named():
    f = Faults.parse(["drop=0.1", "missing=3+4", "overload=13", "voltage=9.5"])
    assert f.drop == 0.1 and f.missing == {3, 4} and f.overload == {13} and f.voltage == 9.5
    with pytest.raises(FaultSpecError, match="drop=2"):
        Faults.parse(["drop=2"])
    with pytest.raises(FaultSpecError, match="unknown fault"):
        Faults.parse(["smoke=1"])
