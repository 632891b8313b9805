"""The Dynamixel bus driver, built on the official ``dynamixel_sdk`` (extra ``[hw]``).

`DynamixelBus` opens the port (2 Mbps by default), checks that every motor answers with its catalogue model
number, configures the motors (return delay 0, extended-position or current-based-position mode, position
P/I/D and feed-forward gains, goal current of grippers), refuses to run below a supply-voltage threshold, and
runs the control cycle: one Fast Sync Read (Sync Read where unsupported) of present current, velocity and
position for all motors, and one Sync Write of goal positions.

Safety policy (docs/hardware.md, "Safety"):

* one process per port: opening takes an exclusive lock on the device (`port_lock`), and a second opener is
  refused with `PortInUseError` naming the holder's PID before it sends a byte;
* every single-motor transaction is retried `retries` times, then a `BusError` names the motor and the error;
* a motor whose state answer is missing in a cycle keeps its last reading; after `max_missed_cycles`
  consecutive silent cycles the read raises `BusError` naming it (the caller stops and torque goes off);
* the Bus Watchdog (address 98) is armed, so the motors stop by themselves if the host goes silent;
* torque goes off when the bus is closed, on any exception inside ``with DynamixelBus(...)`` and on SIGINT,
  SIGTERM, SIGHUP and SIGQUIT (which raise `BusInterrupt`); closing releases the SDK port even if a
  transaction was interrupted, blocks those signals while it works, and retries torque-off until every motor
  confirms or `torque_off_deadline` passes, then raises `TorqueOffError` naming the unconfirmed motors;
* a lost port (the adapter unplugged or its device gone: EIO, ENXIO, ENODEV, a device node that disappeared) is
  not retried: `BusLostError` stops the run at once, and the torque-off that follows reports, in one line, every
  powered motor it could not confirm ("TORQUE MAY STILL BE ON for ids ...").

Positions here are raw motor readings (pulses, multi-turn); `real_robot` converts them to calibrated angles.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import signal
import threading
import time
from dataclasses import dataclass

import numpy as np

from toddlerbot import interrupts
from toddlerbot.actuation.catalogue import MotorModel
from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware import control_table as ct
from toddlerbot.hardware.port_lock import PortInUseError, PortLock
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import MotorSpec

DEFAULT_BAUDRATE = 2_000_000
DEFAULT_RETRIES = 5
"""Attempts per single-motor transaction (a 5 % packet loss then fails one in 3 million transactions)."""
MAX_MISSED_CYCLES = 5
"""Consecutive control cycles a motor may stay silent (its last reading reused) before the run stops."""
BUS_WATCHDOG_S = 0.5
"""Bus Watchdog period, s: a motor that hears nothing for this long stops (holds) by itself."""
TORQUE_OFF_DEADLINE_S = 1.5
"""How long closing keeps retrying torque-off for motors that have not confirmed it, s."""
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT")
                     if hasattr(signal, name))
"""Signals that stop a run with torque off (SIGHUP: the SSH session dropped; SIGQUIT: Ctrl-\\)."""
MIN_SUPPLY_VOLTAGE = 10.5
"""Below this supply voltage (V) the driver refuses to enable torque (a 4-cell battery at ~2.6 V/cell)."""
GRIPPER_GOAL_CURRENT_A = 0.3
"""Goal current of current-based-position grippers, A (bounds the gripping force)."""

try:  # optional at install time: the [hw] extra
    import dynamixel_sdk as sdk
except ImportError:  # pragma: no cover - exercised only without the extra
    sdk = None
try:  # pyserial's tcflush raises termios.error, which is no OSError, when the device is gone
    from termios import error as _TermiosError
except ImportError:  # pragma: no cover - Windows
    _TermiosError = OSError
PORT_ERRORS = (OSError, _TermiosError)
"""What the serial port raises (pyserial's SerialException is an OSError)."""
LOST_ERRNOS = {errno.EIO, errno.ENXIO, errno.ENODEV, errno.EBADF}
"""Errors of a serial device that is gone for good (a USB adapter unplugged, a pty whose other end closed)."""


class HardwareError(ToddlerbotError):
    """The bus or a motor failed; the message names the port or motor and the error."""


class BusError(HardwareError):
    pass


class BusLostError(BusError):
    """The serial port itself is gone (adapter unplugged or dead): nothing on the bus can be reached."""


class TorqueOffError(HardwareError):
    """Some motors did not confirm torque off before the deadline: they may still be powered."""


class BusInterrupt(KeyboardInterrupt):
    """A stop signal (SIGINT, SIGTERM, SIGHUP, SIGQUIT) arrived; raised like Ctrl-C so cleanup runs."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


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
    def from_spec(cls, m: MotorSpec, model: MotorModel) -> BusMotor:
        return cls(m.id, m.joint, model, ct.OPERATING_MODES[m.control_mode], m.kp, m.ki, m.kd, m.kff1, m.kff2)

    @property
    def label(self) -> str:
        return f"motor {self.id} ({self.name}, {self.model.name})"


@dataclass
class BusCounters:
    """What went wrong on the bus since the driver was made (`hw run` prints them after a run)."""

    crc_errors: int = 0
    """Status packets that arrived damaged (a bad CRC, or cut short)."""
    timeouts: int = 0
    """Waits for a status packet that ended with nothing."""
    retries: int = 0
    """Transactions sent again after a failure (a single-motor transaction, a state read, a sync write)."""
    stale_readings: int = 0
    """Motor states missing after a cycle's retry, replaced by the motor's last reading."""

    def describe(self) -> str:
        return (f"{self.retries} retries, {self.crc_errors} CRC errors, {self.timeouts} timeouts, "
                f"{self.stale_readings} stale readings")


@dataclass(frozen=True)
class MotorState:
    """Raw readings of all motors, in the bus's motor order."""

    position: np.ndarray
    """Present position, pulses (multi-turn, int64)."""
    velocity: np.ndarray
    """Present velocity, rad/s."""
    torque: np.ndarray
    """Estimated output torque from present current/load, N*m."""
    fresh: np.ndarray | None = None
    """Per motor: True if read this cycle, False if its answer was missing and the last reading is repeated
    (None: all fresh)."""


def motors_of(description: RobotDescription, ids: set[int] | None = None) -> list[BusMotor]:
    """The description's motors (catalogue models with any fitted parameters), optionally only `ids`."""
    return [BusMotor.from_spec(m, model) for m, model in zip(description.motors, description.motor_models, strict=True)
            if ids is None or m.id in ids]


_deferring = 0
"""How many torque-off sequences are running; while > 0 a stop signal is recorded instead of raised."""
_deferred: list[int] = []


def _raise_bus_interrupt(signum: int, frame: object) -> None:
    if _deferring:
        _deferred.append(signum)  # raised once the torque-off is done (see `DynamixelBus.close`)
        return
    raise BusInterrupt(signum)


def raise_pending_stop() -> None:
    """Raise `BusInterrupt` for a SIGINT that arrived during start-up but was not acted on (its KeyboardInterrupt
    swallowed inside a third-party import; `toddlerbot.interrupts`): call before powering motors."""
    signum = interrupts.take()
    if signum is not None:
        raise BusInterrupt(signum)


def raise_on_stop_signals() -> dict[int, object]:
    """Make every stop signal raise `BusInterrupt` in the main thread (even one the parent process ignored, as a
    shell does for background jobs); returns the previous handlers."""
    return {signum: signal.signal(signum, _raise_bus_interrupt) for signum in STOP_SIGNALS}


def _port_handler(port: str, latency_ms: float | None):
    """The SDK's port handler, with status timeouts computed for a USB-serial latency timer of `latency_ms`
    (None: the SDK's module-wide ``LATENCY_TIMER``, 16 ms, FTDI's factory setting)."""
    if latency_ms is None:
        return sdk.PortHandler(port)

    class Port(sdk.PortHandler):
        def setPacketTimeout(self, packet_length: int) -> None:  # the SDK names it
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = self.tx_time_per_byte * packet_length + 2.0 * latency_ms + 2.0

    return Port(port)


class DynamixelBus:
    """One TTL bus of Dynamixel X-series motors speaking Protocol 2.0."""

    def __init__(
        self,
        port: str,
        motors: list[BusMotor],
        baudrate: int = DEFAULT_BAUDRATE,
        retries: int = DEFAULT_RETRIES,
        min_voltage: float = MIN_SUPPLY_VOLTAGE,
        max_missed_cycles: int = MAX_MISSED_CYCLES,
        watchdog_s: float = BUS_WATCHDOG_S,
        torque_off_deadline: float = TORQUE_OFF_DEADLINE_S,
        latency_ms: float | None = None,
    ) -> None:
        """`watchdog_s`: Bus Watchdog period (0 leaves it off), rounded up to 20 ms, at most 2.54 s;
        `torque_off_deadline`: s of torque-off retries when closing; `latency_ms`: the USB-serial adapter's
        latency timer, which sets how long a status packet is waited for (2 x latency + 2 ms)."""
        if sdk is None:
            raise HardwareError("the Dynamixel driver needs the [hw] extra: pip install 'toddlerbot[hw]'")
        if retries < 1 or max_missed_cycles < 1:
            raise ValueError(f"retries and max_missed_cycles must be >= 1, got {retries}, {max_missed_cycles}")
        if not 0 <= watchdog_s <= ct.BUS_WATCHDOG_MAX * ct.BUS_WATCHDOG_UNIT_S:
            raise ValueError(f"watchdog_s must lie in [0, {ct.BUS_WATCHDOG_MAX * ct.BUS_WATCHDOG_UNIT_S}] s")
        self.port_name = port
        self.motors = motors
        self.ids = [m.id for m in motors]
        self.baudrate = baudrate
        self.retries = retries
        self.min_voltage = min_voltage
        self.max_missed_cycles = max_missed_cycles
        self.watchdog_units = math.ceil(round(watchdog_s / ct.BUS_WATCHDOG_UNIT_S, 6))
        self.torque_off_deadline = torque_off_deadline
        self._powered: set[int] = set()
        """Ids that were sent torque-enable since the port was opened: closing must confirm them off."""
        self.missed = np.zeros(len(motors), dtype=int)
        """Consecutive cycles each motor's state answer has been missing."""
        self._last_state: MotorState | None = None
        self._last_contact = time.perf_counter()
        if latency_ms is not None and not (math.isfinite(latency_ms) and 0 < latency_ms <= 1000):
            raise ValueError(f"latency_ms must lie in (0, 1000] ms, got {latency_ms}")
        self.port = _port_handler(port, latency_ms)
        self._lock = PortLock(port)
        self.ph = sdk.PacketHandler(2.0)
        self.fast_sync_read = True
        self.torque_enabled = False
        self.bytes_tx = 0
        self.bytes_rx = 0
        self.counters = BusCounters()
        self.is_open = False
        self.lost: str | None = None
        """Why the port is gone (None while it works); set by the first port error that means a lost device."""
        self._old_handlers: dict[int, object] = {}
        self._state_reader = sdk.GroupSyncRead(self.port, self.ph, *ct.STATE_BLOCK)
        self._goal_writer = sdk.GroupSyncWrite(self.port, self.ph, ct.ENTRIES["goal_position"].address, 4)
        self._gain_writer = sdk.GroupSyncWrite(self.port, self.ph, *ct.GAINS_BLOCK)
        for i in self.ids:
            self._state_reader.addParam(i)

    # ---- lifecycle -------------------------------------------------------------------------------------
    def open(self) -> DynamixelBus:
        """Lock the port for this process (`PortInUseError` naming the holder's PID, before any byte is sent),
        open it and install the stop-signal handlers (main thread only)."""
        try:
            self._lock.acquire()
            ok = self.port.openPort() and self.port.setBaudRate(self.baudrate)
        except BaseException as exc:
            self._lock.release()
            if isinstance(exc, PortInUseError) or not isinstance(exc, Exception):
                raise
            # a missing device or no permission: OSError, or pyserial's SerialException
            raise HardwareError(f"cannot open serial port {self.port_name}: {exc}") from None
        if not ok:
            self._lock.release()
            raise HardwareError(f"cannot open serial port {self.port_name} at {self.baudrate} baud")
        self.is_open = True
        self._install_signals()
        return self

    def close(self) -> None:
        """Disable torque on every motor (retried until confirmed or the deadline), close the port.

        A stop signal arriving meanwhile is held back and raised afterwards, so a second Ctrl-C cannot cut the
        torque-off short (blocking the signal would not do: numpy's BLAS threads would still receive it). Raises
        `TorqueOffError` naming the motors that never confirmed torque off."""
        global _deferring
        if not self.is_open:
            return
        _deferring += 1
        try:
            self._release_port()
            unconfirmed = self._torque_off_until(time.perf_counter() + self.torque_off_deadline, self._powered)
            with contextlib.suppress(*PORT_ERRORS):  # a lost port fails to close too; it is released either way
                self.port.closePort()
            self.is_open = False
        finally:
            self._lock.release()
            _deferring -= 1
            self._restore_signals()
        signals: list[int] = []
        if not _deferring:  # the outermost close raises what arrived meanwhile
            signals = list(_deferred)
            _deferred.clear()
        if unconfirmed:  # louder than the signal that may have arrived meanwhile
            raise TorqueOffError(self._torque_may_be_on(unconfirmed))
        if signals:
            raise BusInterrupt(signals[0])

    def __enter__(self) -> DynamixelBus:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _install_signals(self) -> None:
        """SIGINT/SIGTERM/SIGHUP/SIGQUIT raise `BusInterrupt`, so `with` blocks and `close()` disable torque."""
        if threading.current_thread() is threading.main_thread() and not self._old_handlers:
            self._old_handlers = raise_on_stop_signals()

    def _restore_signals(self) -> None:
        if self._old_handlers and threading.current_thread() is threading.main_thread():
            for signum, handler in self._old_handlers.items():
                signal.signal(signum, handler)
            self._old_handlers = {}

    def _release_port(self) -> None:
        """Undo what an interrupted SDK transaction leaves behind: the in-use flag and half-read answers."""
        self.port.is_using = False
        with contextlib.suppress(*PORT_ERRORS, AttributeError):  # port already gone: the writes below report it
            self.port.clearPort()

    def _port_error(self, exc: BaseException) -> str:
        """Release the port after `exc` and describe it; a device that is gone sets `lost` and raises
        `BusLostError` (retrying a dead port only delays the torque-off)."""
        self._release_port()
        code = exc.errno if isinstance(exc, OSError) else (exc.args or [None])[0]
        reason = os.strerror(code) if isinstance(code, int) else " ".join(str(exc).split()) or type(exc).__name__
        # pyserial reports a vanished USB device on read as a SerialException without errno ("device disconnected")
        if code in LOST_ERRNOS or not os.path.exists(self.port_name) or "disconnected" in reason:
            self.lost = self.lost or reason
            raise BusLostError(f"bus {self.port_name} lost: {self.lost}; the serial adapter was unplugged or lost "
                               "power")
        return f"serial port error ({reason})"

    def _torque_may_be_on(self, unconfirmed: dict[int, str]) -> str:
        """The one-line report of motors that never confirmed torque off: their ids, why, and what to do."""
        labels = {m.id: m.label for m in self.motors}
        if self.lost:
            why = f"bus lost: {self.lost}"
        elif len(unconfirmed) <= 3:
            why = "; ".join(f"{labels[i]}: {problem}" for i, problem in unconfirmed.items())
        else:
            why = "; ".join(sorted(set(unconfirmed.values())))
        waited = "" if self.lost else f" within {self.torque_off_deadline:g} s"
        return (f"bus {self.port_name}: TORQUE MAY STILL BE ON for ids {_id_list(unconfirmed)}: no torque-off "
                f"confirmation{waited} ({why}); the motors' Bus Watchdog holds them in place with torque on, it does "
                "not make them limp: press the E-stop or cut the motor power")

    # ---- single-motor transactions ---------------------------------------------------------------------
    def _result(self, comm: int, error: int) -> str | None:
        """None on success, else a description of the failure."""
        if comm != sdk.COMM_SUCCESS:
            self._count(comm)
            return self.ph.getTxRxResult(comm)
        if error & 0x7F:
            return self.ph.getRxPacketError(error)
        return None

    def _count(self, comm: int) -> None:
        """Count a failed reception."""
        self.counters.crc_errors += comm == sdk.COMM_RX_CORRUPT
        self.counters.timeouts += comm == sdk.COMM_RX_TIMEOUT

    def _retry(self, motor: BusMotor, what: str, call, allow_alert: bool = False) -> tuple:
        """Run `call` (an SDK transaction returning (..., comm_result, error)) up to `retries` times."""
        problem = ""
        for attempt in range(self.retries):
            self.counters.retries += attempt > 0
            try:
                *values, comm, error = call()
            except IndexError:  # the SDK indexes past the end of a short (but CRC-valid) status packet
                problem = "malformed status packet"
                continue
            except PORT_ERRORS as exc:  # a lost device raises BusLostError; anything else is retried
                problem = self._port_error(exc)
                continue
            problem = self._result(comm, error)
            if problem is None:
                self._last_contact = time.perf_counter()
                if error & 0x80 and not allow_alert:
                    raise BusError(f"{motor.label}: {what}: {self._hardware_error(motor)}")
                return tuple(values)
        raise BusError(f"{motor.label}: {what} failed after {self.retries} attempts: {problem}")

    def _hardware_error(self, motor: BusMotor) -> str:
        try:
            data, comm, _ = self._read_tx_rx(motor.id, ct.ENTRIES["hardware_error_status"].address, 1)
        except IndexError:
            comm = sdk.COMM_RX_CORRUPT
        except PORT_ERRORS as exc:
            return f"hardware alert (hardware error status unreadable: {self._port_error(exc)})"
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
        """Torque off, then clear the Bus Watchdog (an expired one makes the goal registers read-only) and write
        return delay, operating mode, gains and (grippers) goal current."""
        self.disable_torque()
        for m in self.motors:
            self.write(m, "bus_watchdog", 0)
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
        for _ in range(self.retries):
            try:
                if self._state_reader.fastSyncRead() == sdk.COMM_SUCCESS:
                    return True
            except PORT_ERRORS as exc:
                self._port_error(exc)
            except IndexError:
                self._release_port()
        return False

    def enable_torque(self, goal_positions: np.ndarray | None = None) -> None:
        """Set goals to `goal_positions` (default: where the motors are) and enable torque, motor by motor."""
        self.check_voltage()
        goal = self.read_state().position if goal_positions is None else goal_positions
        self.write_goal_positions(goal)
        self._install_signals()
        self.torque_enabled = True
        try:
            for m in self.motors:
                self._powered.add(m.id)
                self.write(m, "torque_enable", 1)
            self._arm_watchdog()
        except BaseException:
            self.disable_torque()
            raise

    def _arm_watchdog(self) -> None:
        """Set every motor's Bus Watchdog with one broadcast Sync Write (armed one by one, the first motor could
        expire while the others are written), then confirm it by a Sync Read; retried for missing answers."""
        if not self.watchdog_units:
            return
        address = ct.ENTRIES["bus_watchdog"].address
        pending = list(self.ids)
        for _ in range(self.retries):
            writer = sdk.GroupSyncWrite(self.port, self.ph, address, 1)
            for i in pending:
                writer.addParam(i, [self.watchdog_units])
            self._send(writer, "bus watchdog")
            try:
                answers, _ = self._sync_read(pending, address, 1)
            except IndexError:
                self._release_port()
                continue
            except PORT_ERRORS as exc:
                self._port_error(exc)
                continue
            pending = [i for i in pending if answers.get(i) != bytes([self.watchdog_units])]
            if not pending:
                return
        labels = ", ".join(m.label for m in self.motors if m.id in pending)
        raise BusError(f"bus {self.port_name}: could not arm the Bus Watchdog of {labels}")

    def disable_torque(self) -> None:
        """Torque off for every motor, confirmed motor by motor; raises `TorqueOffError` naming the motors that
        did not confirm within `torque_off_deadline` s."""
        self._release_port()
        unconfirmed = self._torque_off_until(time.perf_counter() + self.torque_off_deadline, set(self.ids))
        if unconfirmed:
            raise TorqueOffError(self._torque_may_be_on(unconfirmed))

    def _torque_off_until(self, deadline: float, must_confirm: set[int]) -> dict[int, str]:
        """Rounds of (broadcast torque-off, one checked write per unconfirmed motor) until every motor in
        `must_confirm` confirms, the deadline passes or the port is lost; returns {id: last problem} for each of
        those that never confirmed (the others get one round, best effort)."""
        address = ct.ENTRIES["torque_enable"].address
        pending = {m.id: "not tried" for m in self.motors}
        while True:
            try:
                writer = sdk.GroupSyncWrite(self.port, self.ph, address, 1)
                for i in pending:
                    writer.addParam(i, [0])
                writer.txPacket()
            except PORT_ERRORS as exc:
                with contextlib.suppress(BusLostError):
                    self._port_error(exc)
            for m in self.motors:
                if m.id not in pending:
                    continue
                if self.lost:  # nothing can answer through a port that is gone
                    pending[m.id] = "bus lost"
                    continue
                try:
                    comm, error = self.ph.write1ByteTxRx(self.port, m.id, address, 0)
                    problem = self._result(comm, error)
                except IndexError:
                    self._release_port()
                    problem = "malformed status packet"
                except PORT_ERRORS as exc:
                    try:
                        problem = self._port_error(exc)
                    except BusLostError:
                        problem = "bus lost"
                if problem is None:
                    del pending[m.id]
                else:
                    pending[m.id] = problem
            self._powered &= set(pending)
            self.torque_enabled = bool(self._powered)
            if not pending.keys() & must_confirm or self.lost or time.perf_counter() >= deadline:
                break
        return {i: problem for i, problem in pending.items() if i in must_confirm}

    # ---- control cycle ---------------------------------------------------------------------------------
    def read_state(self) -> MotorState:
        """Present current/velocity/position of every motor in one transaction.

        A failed group read is retried once (`retries` times for the very first read) for the motors whose answers
        are missing; motors still missing keep their last reading
        (``fresh`` False) for up to `max_missed_cycles` consecutive cycles, after which `BusError` names them.
        Without an earlier reading, every motor must answer."""
        self._check_watchdog_gap()
        answers, problem = self._group_read(self.ids)
        # a control cycle retries once (time matters); the first read, which has no earlier reading, `retries` times
        for _ in range(1 if self._last_state is not None else self.retries):
            missing = [i for i in self.ids if i not in answers]
            if not missing:
                break
            self.counters.retries += 1
            retried, problem = self._group_read(missing, fast=False)
            answers |= retried
        fresh = np.array([i in answers for i in self.ids])
        self.counters.stale_readings += int(np.count_nonzero(~fresh))
        self.missed = np.where(fresh, 0, self.missed + 1)
        silent = [m.label for m, n in zip(self.motors, self.missed, strict=True) if n >= self.max_missed_cycles]
        if silent or (not fresh.all() and self._last_state is None):
            labels = silent or [m.label for m, ok in zip(self.motors, fresh, strict=True) if not ok]
            raise BusError(
                f"bus {self.port_name}: no state answer from {', '.join(labels)}"
                f"{f' for {self.max_missed_cycles} consecutive cycles' if silent else ''} ({problem})"
            )
        self._last_contact = time.perf_counter()
        last = self._last_state
        n = len(self.ids)
        position = last.position.copy() if last is not None else np.zeros(n, dtype=np.int64)
        velocity = last.velocity.copy() if last is not None else np.zeros(n)
        torque = last.torque.copy() if last is not None else np.zeros(n)
        for k, (i, m) in enumerate(zip(self.ids, self.motors, strict=True)):
            if i in answers:  # the state block: present current/load (2), velocity (4), position (4)
                data = answers[i]
                torque[k] = ct.load_to_torque(ct.decode(data[0:2], True), m.model)
                velocity[k] = float(ct.velocity_to_rad_s(ct.decode(data[2:6], True)))
                position[k] = ct.decode(data[6:10], True)
        state = MotorState(position, velocity, torque, None if fresh.all() else fresh)
        self._last_state = state
        return state

    def _group_read(self, ids: list[int], fast: bool = True) -> tuple[dict[int, bytes], str]:
        """One group read of the state block from `ids`: (answers by id, description of what went wrong)."""
        try:
            if fast and self.fast_sync_read:
                ok, problem = self._read_state_once()
                if ok:
                    return {i: bytes(self._state_reader.data_dict[i]) for i in self.ids}, ""
                return {}, problem
            return self._sync_read(ids, *ct.STATE_BLOCK)
        except IndexError:
            return {}, "malformed status packet"
        except PORT_ERRORS as exc:
            return {}, self._port_error(exc)

    def _sync_read(self, ids: list[int], address: int, length: int) -> tuple[dict[int, bytes], str]:
        """Sync Read of `length` bytes at `address`: every status packet that arrives before the timeout counts,
        whatever its position (a missing motor does not hide the ones after it)."""
        reader = sdk.GroupSyncRead(self.port, self.ph, address, length)
        for i in ids:
            reader.addParam(i)
        comm = reader.txPacket()
        self.bytes_tx += 14 + len(ids)
        if comm != sdk.COMM_SUCCESS:
            return {}, f"sync read: {self.ph.getTxRxResult(comm)}"
        answers: dict[int, bytes] = {}
        problem = ""
        wanted = set(ids)
        while len(answers) < len(ids):
            rx, comm = self.ph.rxPacket(self.port, False)
            if comm != sdk.COMM_SUCCESS:
                self._count(comm)
                problem = f"sync read: {self.ph.getTxRxResult(comm)}"
                break
            dxl_id = rx[sdk.PKT_ID]
            if dxl_id not in wanted or sdk.DXL_MAKEWORD(rx[sdk.PKT_LENGTH_L], rx[sdk.PKT_LENGTH_H]) != length + 4:
                problem = f"sync read: unexpected answer from id {dxl_id}"
                continue
            k = self.ids.index(dxl_id)
            self._check_alert(k, rx[sdk.PKT_ERROR])
            answers[dxl_id] = bytes(rx[sdk.PKT_PARAMETER0 + 1 : sdk.PKT_PARAMETER0 + 1 + length])
            self.bytes_rx += 11 + length
        self.port.is_using = False
        return answers, problem

    def _check_watchdog_gap(self) -> None:
        """After a host stall longer than the Bus Watchdog, the motors have stopped and ignore goals: find
        out which and stop the run instead of sending goals into the void."""
        if not self.watchdog_units or not self.torque_enabled:
            return
        gap = time.perf_counter() - self._last_contact
        if gap <= self.watchdog_units * ct.BUS_WATCHDOG_UNIT_S:
            return
        expired = [m.label for m in self.motors if self.read(m, "bus_watchdog", allow_alert=True) < 0]
        if expired:
            raise BusError(
                f"bus {self.port_name}: the host was silent for {gap:.2f} s, longer than the "
                f"{self.watchdog_units * ct.BUS_WATCHDOG_UNIT_S:g} s Bus Watchdog; stopped motors: {', '.join(expired)}"
            )

    def _read_state_once(self) -> tuple[bool, str]:
        """One Fast Sync Read of the state block from every motor."""
        reader = self._state_reader
        n, length = len(self.ids), ct.STATE_BLOCK[1]
        self.bytes_tx += 14 + n
        comm = reader.fastSyncReadTxPacket()
        if comm == sdk.COMM_SUCCESS:
            raw, comm, _ = self.ph.fastSyncReadRx(self.port, sdk.BROADCAST_ID, (length + 4) * n)
        self._count(comm)
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

    def _check_alert(self, k: int, error: int) -> None:
        if error & 0x80:
            raise BusError(f"{self.motors[k].label}: {self._hardware_error(self.motors[k])}")

    def write_goal_positions(self, pulses: np.ndarray) -> None:
        """One Sync Write of goal positions (pulses, multi-turn); no status packets, so nothing to retry."""
        values = np.asarray(pulses)
        if values.shape != (len(self.ids),) or not np.all(np.isfinite(values)):
            raise BusError(f"bus {self.port_name}: refusing goal positions {values!r}: expected {len(self.ids)} "
                           "finite pulse counts")
        writer = self._goal_writer
        writer.clearParam()
        limit = ct.EXTENDED_POSITION_RANGE
        for dxl_id, value in zip(self.ids, np.clip(values, -limit, limit).astype(np.int64), strict=True):
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
        for attempt in range(self.retries):
            self.counters.retries += attempt > 0
            try:
                comm = writer.txPacket()
            except PORT_ERRORS as exc:
                self._port_error(exc)
                comm = sdk.COMM_TX_FAIL
            if comm == sdk.COMM_SUCCESS:
                return
        raise BusError(f"bus {self.port_name}: sync write of {what} failed: {self.ph.getTxRxResult(comm)}")


def _id_list(ids: object) -> str:
    """Motor ids as runs: [1, 2, 3, 5] -> '1-3, 5'."""
    runs: list[list[int]] = []
    for i in sorted(ids):
        if runs and i == runs[-1][-1] + 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    return ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)
