"""A Dynamixel Protocol 2.0 bus emulator (pure Python) serving the spec's motors on a pseudo-terminal.

Each emulated motor has a control table (`control_table.ENTRIES`) with the factory defaults of its model,
refuses EEPROM writes while torque is enabled (access error), validates operating modes, and answers ping,
read, write, sync read, fast sync read, sync write, bulk read, reboot and factory reset like an X-series
motor (`emulated_motor`). The motion behind the registers comes from a plant (`plant`):

* `SimplePlant`: every motor is an independent inertia driven by the actuator model
  (`toddlerbot.actuation.model.motor_torque`) with the gains in its control table.
* `HilPlant` (hardware in the loop): the MuJoCo model of the whole floating robot on the floor or a terrain; the same
  actuator model runs every 1 ms physics step, paced to wall-clock time in a background thread.

Every motor has a hidden mounting offset (pulses): the reading at motor angle 0, which the zero-point
calibration recovers. As on the real motors, the multi-turn count is lost at power-up and reboot, so the first
reading lies in 0..4095.

Faults (`Faults`): dropped instruction packets, corrupted status packets, missing ids, a low supply voltage
and motors that report an overload (hardware error status bit 5, alert flag in every status packet, torque
forced off).

Bus Watchdog (address 98, as the X-series firmware): while torque is on and the register holds 1..127, a motor
that hears no instruction packet (addressed to it or broadcast) for that many 20 ms units stops: its goal
position becomes its present position (torque stays on, it holds), the register reads -1, and goal writes are
refused with a data range error until the register is written again (0 clears it).

Malformed packets never stop the emulator: a read outside the control table is answered with an access error
(Read, Sync Read), a Fast Sync Read whose answer would not fit a packet is ignored, and instructions too short
for their parameters get a data length error or are ignored (broadcasts).
"""

from __future__ import annotations

import contextlib
import math
import os
import random
import select
import threading
import time
import tty
from dataclasses import dataclass, field

from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware import protocol as p
from toddlerbot.hardware.control_table import (
    BUS_WATCHDOG_UNIT_S,
    PULSES_PER_REV,
    TABLE_SIZE,
    decode,
    encode,
)
from toddlerbot.hardware.emulated_motor import EmulatedMotor
from toddlerbot.hardware.hil_kicks import Kick
from toddlerbot.hardware.plant import HilPlant, SimplePlant
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.terrain import TerrainSpec

SUPPLY_VOLTAGE = 12.0
"""Default emulated supply voltage, V."""
MAX_VOLTAGE = 30.0
"""Largest supply voltage a fault may set, V (X-series motors are rated to 14.8 V; 30 V catches typos)."""


class FaultSpecError(ToddlerbotError):
    pass


@dataclass(frozen=True)
class Faults:
    """Injected faults. Probabilities apply per status packet a motor would send."""

    drop: float = 0.0
    """Probability that a motor ignores an instruction addressed to it (no status packet)."""
    corrupt: float = 0.0
    """Probability that a status packet has one byte flipped."""
    missing: frozenset[int] = frozenset()
    """Ids that never answer (motor unplugged)."""
    voltage: float = SUPPLY_VOLTAGE
    """Supply voltage, V (below a motor's Min Voltage Limit it also raises the input-voltage error)."""
    overload: frozenset[int] = frozenset()
    """Ids that report an overload hardware error."""
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("drop", "corrupt"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):  # also refuses NaN
                raise FaultSpecError(f"fault {name}={value}: a probability must lie in [0, 1]")
        if not (isinstance(self.voltage, (int, float)) and math.isfinite(self.voltage)
                and 0.0 <= self.voltage <= MAX_VOLTAGE):
            raise FaultSpecError(f"fault voltage={self.voltage}: expected a supply voltage in [0, {MAX_VOLTAGE:g}] V")
        for name in ("missing", "overload"):
            bad = sorted(i for i in getattr(self, name) if not 0 <= i <= p.MAX_ID)
            if bad:
                raise FaultSpecError(f"fault {name}={bad[0]}: motor ids lie in 0..{p.MAX_ID}")

    @classmethod
    def parse(cls, items: list[str]) -> Faults:
        """From ``key=value`` strings: drop=0.1, corrupt=0.05, missing=7 (or 7+8), voltage=9.5, overload=13."""
        values: dict = {}
        for item in items:
            key, sep, value = item.partition("=")
            try:
                if not sep:
                    raise ValueError("expected key=value")
                if key in ("drop", "corrupt"):
                    values[key] = float(value)
                    if not 0.0 <= values[key] <= 1.0:  # also refuses NaN
                        raise ValueError("a probability must lie in [0, 1]")
                elif key in ("missing", "overload"):
                    values[key] = values.get(key, frozenset()) | {int(v) for v in value.split("+")}
                elif key == "voltage":
                    values[key] = float(value)
                    if not 0.0 <= values[key] <= MAX_VOLTAGE:  # also refuses NaN and inf
                        raise ValueError(f"expected a supply voltage in [0, {MAX_VOLTAGE:g}] V")
                elif key == "seed":
                    values[key] = int(value)
                else:
                    raise ValueError("unknown fault; expected drop, corrupt, missing, voltage, overload or seed")
            except ValueError as exc:
                raise FaultSpecError(f"fault {item!r}: {exc}") from None
        return cls(**values)


@dataclass
class BusStats:
    packets_in: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    crc_errors: int = 0
    by_instruction: dict[int, int] = field(default_factory=dict)


class EmulatedBus:
    """The motors of a robot on one Protocol 2.0 bus: `handle` maps an instruction packet to the bytes sent back."""

    def __init__(
        self,
        description: RobotDescription,
        hil: bool = False,
        faults: Faults | None = None,
        fast_sync_read: bool = True,
        offsets_seed: int = 0,
        kicks: tuple[Kick, ...] = (),
        terrain: TerrainSpec | None = None,
        terrain_seed: int = 0,
    ) -> None:
        self.description = description
        self.spec = description.spec
        self.faults = faults or Faults()
        self.fast_sync_read = fast_sync_read
        self._rng = random.Random(self.faults.seed)
        offset_rng = random.Random(offsets_seed)
        self.motors = []
        for ms, model in zip(description.motors, description.motor_models, strict=True):
            motor = EmulatedMotor(ms.id, ms.joint, model, offset_rng.randrange(0, PULSES_PER_REV))
            motor.overloaded = ms.id in self.faults.overload
            motor.overloaded_refresh()
            self.motors.append(motor)
        self.lock = threading.Lock()
        self.stats = BusStats()
        if kicks and not hil:
            raise ToddlerbotError("--kick pushes the simulated robot: it needs --hil")
        if terrain is not None and not hil:
            raise ToddlerbotError(f"--terrain {terrain}: the ground is the simulated robot's: it needs --hil")
        self.plant: SimplePlant | HilPlant = HilPlant(self.motors, description, kicks, terrain, terrain_seed) if hil \
            else SimplePlant(self.motors)
        for motor in self.motors:
            self._power_up(motor)

    def _power_up(self, motor: EmulatedMotor) -> None:
        """Drop the multi-turn count: the reading comes back within one turn (0..4095)."""
        self.plant.update()
        present = motor.get("present_position")
        raw = present - motor.get("homing_offset") - motor.turn_offset
        turn_offset = -(raw // PULSES_PER_REV) * PULSES_PER_REV
        motor.set("present_position", present - motor.turn_offset + turn_offset)
        motor.turn_offset = turn_offset

    def motor(self, dxl_id: int) -> EmulatedMotor | None:
        if dxl_id in self.faults.missing:
            return None
        for m in self.motors:
            if m.id == dxl_id and m.id not in self.faults.missing:
                return m
        return None

    def _answering(self, dxl_id: int) -> EmulatedMotor | None:
        """The motor if present and the drop fault spares this packet."""
        m = self.motor(dxl_id)
        if m is None or (self.faults.drop and self._rng.random() < self.faults.drop):
            return None
        return m

    def _status(self, motor: EmulatedMotor, error: int, params: bytes = b"") -> bytes:
        packet = p.build_status(motor.id, error | motor.error_flags(self.faults.voltage), params)
        return self._maybe_corrupt(packet)

    def _maybe_corrupt(self, packet: bytes) -> bytes:
        if self.faults.corrupt and self._rng.random() < self.faults.corrupt:
            i = self._rng.randrange(7, len(packet))
            packet = packet[:i] + bytes([packet[i] ^ 0x5A]) + packet[i + 1 :]
        return packet

    # -- instruction handling ------------------------------------------------------------------------------
    def handle(self, packet: p.Packet | p.CrcMismatch) -> bytes:
        with self.lock:
            self.plant.update()
            now = time.perf_counter()
            if isinstance(packet, p.Packet):
                # heard first, then expire: a packet that waited in the pty while this thread was descheduled
                # proves the host was alive
                for m in self.motors:
                    if packet.id in (m.id, p.BROADCAST_ID):
                        m.last_heard = now
            self._expire_watchdogs(now)
            for m in self.motors:
                m.set("present_input_voltage", round(self.faults.voltage * 10))
            self.stats.packets_in += 1
            if isinstance(packet, p.CrcMismatch):
                self.stats.crc_errors += 1
                m = self._answering(packet.id) if packet.id != p.BROADCAST_ID else None
                return self._status(m, p.ERR_CRC) if m else b""
            self.stats.by_instruction[packet.instruction] = self.stats.by_instruction.get(packet.instruction, 0) + 1
            out = self._dispatch(packet)
            self.stats.bytes_out += len(out)
            return out

    def check_watchdogs(self) -> None:
        """Let Bus Watchdogs expire while no packet arrives (the server calls this when the bus is idle)."""
        with self.lock:
            self.plant.update()
            self._expire_watchdogs(time.perf_counter())

    def _expire_watchdogs(self, now: float) -> None:
        for m in self.motors:
            period = m.get("bus_watchdog")
            if m.torque_on and period > 0 and now - m.last_heard > period * BUS_WATCHDOG_UNIT_S:
                m.watchdog_expire()

    def _dispatch(self, pk: p.Packet) -> bytes:
        inst, params = pk.instruction, pk.params
        if inst == p.PING:
            targets = self.motors if pk.id == p.BROADCAST_ID else [self.motor(pk.id)]
            out = b""
            for m in targets:
                m = m and self._answering(m.id)
                if m:
                    out += self._status(m, 0, encode(m.get("model_number"), 2) + bytes([m.get("firmware_version")]))
            return out
        if inst in (p.READ, p.WRITE, p.REBOOT, p.FACTORY_RESET):
            return self._single(pk)
        if inst == p.SYNC_WRITE:
            if len(params) < 4:
                return b""
            address, length = decode(params[0:2], False), decode(params[2:4], False)
            stride = 1 + length
            for i in range(4, len(params) - stride + 1, stride):
                m = self.motor(params[i])
                if m is not None and not (self.faults.drop and self._rng.random() < self.faults.drop):
                    m.write(address, params[i + 1 : i + stride])
            return b""
        if inst in (p.SYNC_READ, p.FAST_SYNC_READ):
            if len(params) < 5 or pk.id != p.BROADCAST_ID:
                return b""
            address, length = decode(params[0:2], False), decode(params[2:4], False)
            ids = list(params[4:])
            if inst == p.SYNC_READ:
                return b"".join(self._read_status(i, address, length) for i in ids)
            return self._fast_sync_read(ids, address, length) if self.fast_sync_read else b""
        if inst == p.BULK_READ:
            out = b""
            for i in range(0, len(params) - 4, 5):
                address, length = decode(params[i + 1 : i + 3], False), decode(params[i + 3 : i + 5], False)
                out += self._read_status(params[i], address, length)
            return out
        if pk.id != p.BROADCAST_ID:
            m = self._answering(pk.id)
            return self._status(m, p.ERR_INSTRUCTION) if m else b""
        return b""

    def _read_status(self, dxl_id: int, address: int, length: int) -> bytes:
        m = self._answering(dxl_id)
        if m is None or m.get("status_return_level") < 1:
            return b""
        error, data = m.read(address, length)
        return self._status(m, error, data)

    def _single(self, pk: p.Packet) -> bytes:
        broadcast = pk.id == p.BROADCAST_ID
        targets = self.motors if broadcast else [self.motor(pk.id)]
        out = b""
        for m in targets:
            if m is None or (self.faults.drop and self._rng.random() < self.faults.drop):
                continue
            inst, params = pk.instruction, pk.params
            if inst == p.READ:
                if broadcast:
                    continue
                if len(params) != 4:
                    out += self._status(m, p.ERR_DATA_LENGTH)
                    continue
                out += self._read_status(m.id, decode(params[0:2], False), decode(params[2:4], False))
                continue
            if inst == p.WRITE:
                error = m.write(decode(params[0:2], False), params[2:]) if len(params) > 2 else p.ERR_DATA_LENGTH
            elif inst == p.REBOOT:
                m.set("torque_enable", 0)
                self._power_up(m)
                error = 0
            else:  # factory reset: 0xFF everything, 0x01 all but the id, 0x02 all but id and baud rate
                option = params[0] if params else 0xFF
                if option not in (0x01, 0x02, 0xFF):
                    error = p.ERR_DATA_RANGE
                elif m.torque_on:
                    error = p.ERR_ACCESS
                else:
                    m.factory_reset(keep_id=option != 0xFF)
                    m.overloaded_refresh()
                    self._power_up(m)
                    error = 0
            if not broadcast and m.get("status_return_level") >= 2:
                out += self._status(m, error)
        return out

    def _fast_sync_read(self, ids: list[int], address: int, length: int) -> bytes:
        """One status packet for all ids: per motor ERR, ID, DATA, CRC, where each CRC covers the packet so far
        (the last one is the packet's CRC). A motor that does not answer breaks the chain: the packet ends there.
        A request outside the control table, or one whose answer would not fit a packet, is ignored."""
        n = len(ids)
        if length < 1 or address + length > TABLE_SIZE or 1 + n * (length + 4) > p.MAX_LENGTH:
            return b""
        head = p.HEADER + bytes([p.BROADCAST_ID]) + (1 + n * (length + 4)).to_bytes(2, "little") + bytes([p.STATUS])
        packet, crc = bytearray(head), p.crc16(head)
        for dxl_id in ids:
            m = self._answering(dxl_id)
            if m is None:
                break
            error, data = m.read(address, length)
            segment = bytes([error | m.error_flags(self.faults.voltage), dxl_id]) + (bytes(length) if error else data)
            crc = p.crc16(segment, crc)
            packet += segment + crc.to_bytes(2, "little")
            crc = p.crc16(packet[-2:], crc)
        return self._maybe_corrupt(bytes(packet))

    # -- serving ---------------------------------------------------------------------------------------
    def start(self) -> None:
        self.plant.start(self.lock)

    def stop(self) -> None:
        self.plant.stop()


class PtyServer:
    """Serves an `EmulatedBus` on a pseudo-terminal until `stop()` (or forever in `serve_forever`)."""

    def __init__(self, bus: EmulatedBus) -> None:
        self.bus = bus
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.parser = p.PacketParser()

    def serve_forever(self) -> None:
        self.bus.start()
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([self.master], [], [], 0.02)
                if not ready:
                    self.bus.check_watchdogs()
                    continue
                try:
                    data = os.read(self.master, 4096)
                except OSError:
                    continue
                self.bus.stats.bytes_in += len(data)
                for packet in self.parser.feed(data):
                    reply = self.bus.handle(packet)
                    while reply:
                        reply = reply[os.write(self.master, reply) :]
        finally:
            self.bus.stop()

    def start(self) -> PtyServer:
        self._thread = threading.Thread(target=self.serve_forever, name="dxl-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)

    def __enter__(self) -> PtyServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
