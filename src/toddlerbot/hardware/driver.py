"""The Dynamixel bus driver, built on the official ``dynamixel_sdk`` (extra ``[hw]``).

`DynamixelBus` opens the port (2 Mbps by default), checks that every motor answers with its catalogue model
number, configures the motors (return delay 0, extended-position or current-based-position mode, position
P/I/D and feed-forward gains, goal current of grippers), refuses to run below a supply-voltage threshold, and
runs the control cycle: one Fast Sync Read (Sync Read where unsupported) of present current, velocity and
position for all motors, and one Sync Write of goal positions. Every transaction is retried a fixed number of
times; after that a `BusError` names the motor(s) and the error. Torque is disabled when the bus is closed,
on exceptions inside ``with DynamixelBus(...)``, on Ctrl-C and on SIGTERM.

Positions here are raw motor readings (pulses, multi-turn); `real_robot` converts them to calibrated angles.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from dataclasses import dataclass

import numpy as np

from toddlerbot.actuation.catalogue import MotorModel, default_catalogue
from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware import control_table as ct
from toddlerbot.robot.spec import MotorSpec, RobotSpec

DEFAULT_BAUDRATE = 2_000_000
DEFAULT_RETRIES = 3
MIN_SUPPLY_VOLTAGE = 10.5
"""Below this supply voltage (V) the driver refuses to enable torque (a 4-cell battery at ~2.6 V/cell)."""
GRIPPER_GOAL_CURRENT_A = 0.3
"""Goal current of current-based-position grippers, A (bounds the gripping force)."""

try:  # optional at install time: the [hw] extra
    import dynamixel_sdk as sdk
except ImportError:  # pragma: no cover - exercised only without the extra
    sdk = None


class HardwareError(ToddlerbotError):
    """The bus or a motor failed; the message names the port or motor and the error."""


class BusError(HardwareError):
    pass


@dataclass(frozen=True)
class BusMotor:
    id: int
    name: str
    model: MotorModel
    mode: int
    """Operating mode register value."""
    kp: int
    ki: int
    kd: int
    kff1: int
    kff2: int

    @classmethod
    def from_spec(cls, m: MotorSpec) -> BusMotor:
        return cls(m.id, m.joint, default_catalogue()[m.model], ct.OPERATING_MODES[m.control_mode],
                   m.kp, m.ki, m.kd, m.kff1, m.kff2)

    @property
    def label(self) -> str:
        return f"motor {self.id} ({self.name}, {self.model.name})"


@dataclass(frozen=True)
class MotorState:
    """Raw readings of all motors, in the bus's motor order."""

    position: np.ndarray
    """Present position, pulses (multi-turn, int64)."""
    velocity: np.ndarray
    """Present velocity, rad/s."""
    torque: np.ndarray
    """Estimated output torque from present current/load, N*m."""


def motors_of(spec: RobotSpec, ids: set[int] | None = None) -> list[BusMotor]:
    return [BusMotor.from_spec(m) for m in spec.motors_by_id if ids is None or m.id in ids]


class DynamixelBus:
    """One TTL bus of Dynamixel X-series motors speaking Protocol 2.0."""

    def __init__(
        self,
        port: str,
        motors: list[BusMotor],
        baudrate: int = DEFAULT_BAUDRATE,
        retries: int = DEFAULT_RETRIES,
        min_voltage: float = MIN_SUPPLY_VOLTAGE,
    ) -> None:
        if sdk is None:
            raise HardwareError("the Dynamixel driver needs the [hw] extra: pip install 'toddlerbot[hw]'")
        if retries < 1:
            raise ValueError(f"retries must be >= 1, got {retries}")
        self.port_name = port
        self.motors = motors
        self.ids = [m.id for m in motors]
        self.baudrate = baudrate
        self.retries = retries
        self.min_voltage = min_voltage
        self.port = sdk.PortHandler(port)
        self.ph = sdk.PacketHandler(2.0)
        self.fast_sync_read = True
        self.torque_enabled = False
        self.bytes_tx = 0
        self.bytes_rx = 0
        self.is_open = False
        self._old_sigterm = None
        self._state_reader = sdk.GroupSyncRead(self.port, self.ph, *ct.STATE_BLOCK)
        self._goal_writer = sdk.GroupSyncWrite(self.port, self.ph, ct.ENTRIES["goal_position"].address, 4)
        self._gain_writer = sdk.GroupSyncWrite(self.port, self.ph, *ct.GAINS_BLOCK)
        for i in self.ids:
            self._state_reader.addParam(i)

    # ---- lifecycle -------------------------------------------------------------------------------------
    def open(self) -> DynamixelBus:
        try:
            ok = self.port.openPort() and self.port.setBaudRate(self.baudrate)
        except Exception as exc:  # pyserial raises SerialException/OSError for a missing device
            raise HardwareError(f"cannot open serial port {self.port_name}: {exc}") from None
        if not ok:
            raise HardwareError(f"cannot open serial port {self.port_name} at {self.baudrate} baud")
        self.is_open = True
        return self

    def close(self) -> None:
        """Disable torque (best effort, every motor) and close the port."""
        if not self.is_open:
            return
        with contextlib.suppress(HardwareError):
            self.disable_torque()
        self.port.closePort()
        self.is_open = False
        self._restore_signals()

    def __enter__(self) -> DynamixelBus:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _install_signals(self) -> None:
        """SIGTERM raises KeyboardInterrupt like Ctrl-C, so `with` blocks and `close()` disable torque."""
        if threading.current_thread() is not threading.main_thread() or self._old_sigterm is not None:
            return

        def _interrupt(signum: int, frame: object) -> None:
            raise KeyboardInterrupt(f"signal {signum}")

        self._old_sigterm = signal.signal(signal.SIGTERM, _interrupt)

    def _restore_signals(self) -> None:
        if self._old_sigterm is not None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, self._old_sigterm)
            self._old_sigterm = None

    # ---- single-motor transactions ---------------------------------------------------------------------
    def _result(self, comm: int, error: int) -> str | None:
        """None on success, else a description of the failure."""
        if comm != sdk.COMM_SUCCESS:
            return self.ph.getTxRxResult(comm)
        if error & 0x7F:
            return self.ph.getRxPacketError(error)
        return None

    def _retry(self, motor: BusMotor, what: str, call, allow_alert: bool = False) -> tuple:
        """Run `call` (an SDK transaction returning (..., comm_result, error)) up to `retries` times."""
        problem = ""
        for _ in range(self.retries):
            try:
                *values, comm, error = call()
            except IndexError:  # the SDK indexes past the end of a short (but CRC-valid) status packet
                problem = "malformed status packet"
                continue
            problem = self._result(comm, error)
            if problem is None:
                if error & 0x80 and not allow_alert:
                    raise BusError(f"{motor.label}: {what}: {self._hardware_error(motor)}")
                return tuple(values)
        raise BusError(f"{motor.label}: {what} failed after {self.retries} attempts: {problem}")

    def _hardware_error(self, motor: BusMotor) -> str:
        try:
            data, comm, _ = self._read_tx_rx(motor.id, ct.ENTRIES["hardware_error_status"].address, 1)
        except IndexError:
            comm = sdk.COMM_RX_CORRUPT
        if comm != sdk.COMM_SUCCESS:
            return "hardware alert (hardware error status unreadable)"
        return f"hardware error: {ct.describe_hardware_error(data[0])}"

    def read(self, motor: BusMotor, entry: str, allow_alert: bool = False) -> int:
        e = ct.ENTRIES[entry]
        (data,) = self._retry(motor, f"read {entry}", lambda: self._read_tx_rx(motor.id, e.address, e.size),
                              allow_alert)
        return ct.decode(data, e.signed)

    def _read_tx_rx(self, dxl_id: int, address: int, length: int) -> tuple[bytes, int, int]:
        """Read instruction through the SDK's packet handler, also checking the status packet's length (the
        SDK's readTxRx would return CRC bytes as data from a short status packet)."""
        tx = [0] * 14
        tx[sdk.PKT_ID], tx[sdk.PKT_LENGTH_L], tx[sdk.PKT_INSTRUCTION] = dxl_id, 7, sdk.INST_READ
        tx[sdk.PKT_PARAMETER0 : sdk.PKT_PARAMETER0 + 4] = list(ct.encode(address, 2) + ct.encode(length, 2))
        rx, comm, error = self.ph.txRxPacket(self.port, tx)
        if comm == sdk.COMM_SUCCESS and sdk.DXL_MAKEWORD(rx[sdk.PKT_LENGTH_L], rx[sdk.PKT_LENGTH_H]) != length + 4:
            comm = sdk.COMM_RX_CORRUPT
        data = bytes(rx[sdk.PKT_PARAMETER0 + 1 : sdk.PKT_PARAMETER0 + 1 + length]) if comm == sdk.COMM_SUCCESS else b""
        return data, comm, error

    def write(self, motor: BusMotor, entry: str, value: int, allow_alert: bool = False) -> None:
        e = ct.ENTRIES[entry]
        writer = {1: self.ph.write1ByteTxRx, 2: self.ph.write2ByteTxRx, 4: self.ph.write4ByteTxRx}[e.size]
        raw = int(value) & ((1 << (8 * e.size)) - 1)
        self._retry(motor, f"write {entry}={value}", lambda: writer(self.port, motor.id, e.address, raw), allow_alert)

    def ping(self, motor: BusMotor) -> int:
        """The model number the motor reports."""
        (number,) = self._retry(motor, "ping", lambda: self.ph.ping(self.port, motor.id))
        return number

    # ---- setup -----------------------------------------------------------------------------------------
    def scan(self) -> dict[int, int]:
        """Ping every motor and check its model number; raises naming every missing or wrong motor."""
        problems, found = [], {}
        for m in self.motors:
            try:
                found[m.id] = self.ping(m)
            except BusError as exc:
                problems.append(f"{m.label} does not answer ({exc})")
                continue
            if found[m.id] != m.model.model_number:
                problems.append(
                    f"{m.label}: reports model number {found[m.id]} ({ct.model_name(found[m.id])}), "
                    f"expected {m.model.model_number}"
                )
        if problems:
            raise BusError(f"bus {self.port_name}: " + "; ".join(problems))
        return found

    def check_voltage(self) -> float:
        """Lowest supply voltage any motor sees, V; refuses (BusError) below `min_voltage`."""
        readings = {m.id: self.read(m, "present_input_voltage", True) * ct.VOLT_PER_UNIT for m in self.motors}
        low_id = min(readings, key=readings.get)
        if readings[low_id] < self.min_voltage:
            motor = next(m for m in self.motors if m.id == low_id)
            raise BusError(
                f"supply voltage too low: {motor.label} reads {readings[low_id]:.1f} V, "
                f"need at least {self.min_voltage:.1f} V; charge the battery or check the power supply"
            )
        return readings[low_id]

    def configure(self) -> None:
        """Torque off, then write return delay, operating mode, gains and (grippers) goal current."""
        self.disable_torque()
        for m in self.motors:
            self.write(m, "return_delay_time", 0)
            self.write(m, "operating_mode", m.mode)
            self.write(m, "position_p_gain", m.kp)
            self.write(m, "position_i_gain", m.ki)
            self.write(m, "position_d_gain", m.kd)
            self.write(m, "feedforward_1st_gain", m.kff1)
            self.write(m, "feedforward_2nd_gain", m.kff2)
            if m.mode == ct.MODE_CURRENT_BASED_POSITION:
                t = ct.traits(m.model)
                self.write(m, "goal_current", round(GRIPPER_GOAL_CURRENT_A / t.current_unit_a))
        self.fast_sync_read = self._fast_sync_read_works()

    def _fast_sync_read_works(self) -> bool:
        """Whether every motor answers Fast Sync Read (firmware support); else the cycle uses Sync Read."""
        return any(self._state_reader.fastSyncRead() == sdk.COMM_SUCCESS for _ in range(self.retries))

    def enable_torque(self, goal_positions: np.ndarray | None = None) -> None:
        """Set goals to `goal_positions` (default: where the motors are) and enable torque, motor by motor."""
        self.check_voltage()
        goal = self.read_state().position if goal_positions is None else goal_positions
        self.write_goal_positions(goal)
        self._install_signals()
        self.torque_enabled = True
        try:
            for m in self.motors:
                self.write(m, "torque_enable", 1)
        except BaseException:
            self.disable_torque()
            raise

    def disable_torque(self) -> None:
        """Torque off for every motor: one broadcast sync write, then a checked write per motor."""
        writer = sdk.GroupSyncWrite(self.port, self.ph, ct.ENTRIES["torque_enable"].address, 1)
        for i in self.ids:
            writer.addParam(i, [0])
        writer.txPacket()
        failures = []
        for m in self.motors:
            try:
                self.write(m, "torque_enable", 0, allow_alert=True)
            except BusError as exc:
                failures.append(str(exc))
        self.torque_enabled = False
        if failures:
            raise BusError("could not confirm torque off: " + "; ".join(failures))

    # ---- control cycle ---------------------------------------------------------------------------------
    def read_state(self) -> MotorState:
        """Present current/velocity/position of every motor in one transaction (retried)."""
        problem = ""
        for _ in range(self.retries):
            try:
                ok, problem = self._read_state_once()
            except IndexError:
                ok, problem = False, "malformed status packet"
            if ok:
                break
        else:
            raise BusError(
                f"bus {self.port_name}: state read failed after {self.retries} attempts: {problem}"
                f"{self._silent_motors()}"
            )
        address = ct.STATE_BLOCK[0]
        get = self._state_reader.getData
        raw_load = [ct.decode(ct.encode(get(i, address, 2), 2), True) for i in self.ids]
        vel = [ct.decode(ct.encode(get(i, address + 2, 4), 4), True) for i in self.ids]
        pos = [ct.decode(ct.encode(get(i, address + 6, 4), 4), True) for i in self.ids]
        torque = np.array([ct.load_to_torque(r, m.model) for r, m in zip(raw_load, self.motors, strict=True)])
        return MotorState(np.array(pos, dtype=np.int64), ct.velocity_to_rad_s(vel), torque)

    def _read_state_once(self) -> tuple[bool, str]:
        reader = self._state_reader
        n, length = len(self.ids), ct.STATE_BLOCK[1]
        self.bytes_tx += 14 + n
        if self.fast_sync_read:
            comm = reader.fastSyncReadTxPacket()
            if comm == sdk.COMM_SUCCESS:
                raw, comm, _ = self.ph.fastSyncReadRx(self.port, sdk.BROADCAST_ID, (length + 4) * n)
            if comm != sdk.COMM_SUCCESS:
                return False, f"fast sync read: {self.ph.getTxRxResult(comm)}"
            if len(raw) != (length + 4) * n:
                return False, f"fast sync read: answer of {len(raw)} bytes, expected {(length + 4) * n}"
            self.bytes_rx += 8 + len(raw)
            for k in range(n):
                error, dxl_id = raw[k * (length + 4)], raw[k * (length + 4) + 1]
                if dxl_id != self.ids[k]:
                    return False, f"fast sync read: answer {k} comes from id {dxl_id}, expected {self.ids[k]}"
                reader.data_dict[dxl_id] = bytearray(raw[k * (length + 4) + 2 : k * (length + 4) + 2 + length])
                self._check_alert(k, error)
            reader.last_result = True
            return True, ""
        comm = reader.txPacket()
        if comm != sdk.COMM_SUCCESS:
            return False, f"sync read: {self.ph.getTxRxResult(comm)}"
        for k, dxl_id in enumerate(self.ids):
            data, comm, error = self.ph.readRx(self.port, dxl_id, length)
            if comm != sdk.COMM_SUCCESS:
                reader.last_result = False
                return False, f"sync read: {self.motors[k].label}: {self.ph.getTxRxResult(comm)}"
            if len(data) != length:
                reader.last_result = False
                return False, f"sync read: {self.motors[k].label}: {len(data)} data bytes, expected {length}"
            self.bytes_rx += 11 + length
            reader.data_dict[dxl_id] = data
            self._check_alert(k, error)
        reader.last_result = True
        return True, ""

    def _check_alert(self, k: int, error: int) -> None:
        if error & 0x80:
            raise BusError(f"{self.motors[k].label}: {self._hardware_error(self.motors[k])}")

    def _silent_motors(self) -> str:
        """After a failed group read: which motors do not answer a ping (names them in the error)."""
        silent = []
        for m in self.motors:
            _number, comm, _ = self.ph.ping(self.port, m.id)
            if comm != sdk.COMM_SUCCESS:
                silent.append(m.label)
        return f" (not answering: {', '.join(silent)})" if silent else ""

    def write_goal_positions(self, pulses: np.ndarray) -> None:
        """One Sync Write of goal positions (pulses, multi-turn); no status packets, so nothing to retry."""
        writer = self._goal_writer
        writer.clearParam()
        limit = ct.EXTENDED_POSITION_RANGE
        for dxl_id, value in zip(self.ids, np.clip(np.asarray(pulses, dtype=np.int64), -limit, limit), strict=True):
            writer.addParam(dxl_id, list(ct.encode(int(value), 4)))
        self._send(writer, "goal positions")
        self.bytes_tx += 14 + 5 * len(self.ids)

    def write_gains(self, kp: np.ndarray, kd: np.ndarray) -> None:
        """One Sync Write of position D, I and P gains (firmware units; I taken from the spec)."""
        writer = self._gain_writer
        writer.clearParam()
        for m, p_gain, d_gain in zip(self.motors, kp, kd, strict=True):
            data = ct.encode(int(d_gain), 2) + ct.encode(m.ki, 2) + ct.encode(int(p_gain), 2)
            writer.addParam(m.id, list(data))
        self._send(writer, "gains")

    def _send(self, writer, what: str) -> None:
        for _ in range(self.retries):
            comm = writer.txPacket()
            if comm == sdk.COMM_SUCCESS:
                return
        raise BusError(f"bus {self.port_name}: sync write of {what} failed: {self.ph.getTxRxResult(comm)}")
