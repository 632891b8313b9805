"""A Dynamixel Protocol 2.0 bus emulator (pure Python) serving the spec's motors on a pseudo-terminal.

Each emulated motor has a control table (`control_table.ENTRIES`) with the factory defaults of its model,
refuses EEPROM writes while torque is enabled (access error), validates operating modes, and answers ping,
read, write, sync read, fast sync read, sync write, bulk read, reboot and factory reset like an X-series
motor. The motion behind the registers comes from a plant:

* `SimplePlant`: every motor is an independent inertia driven by the actuator model
  (`toddlerbot.actuation.model.motor_torque`) with the gains in its control table.
* `HilPlant` (hardware in the loop): the MuJoCo model of the whole floating robot on the floor; the same
  actuator model runs every 1 ms physics step, paced to wall-clock time in a background thread.

Every motor has a hidden mounting offset (pulses): the reading at motor angle 0, which the zero-point
calibration recovers. As on the real motors, the multi-turn count is lost at power-up and reboot, so the first
reading lies in 0..4095.

Faults (`Faults`): dropped instruction packets, corrupted status packets, missing ids, a low supply voltage
and motors that report an overload (hardware error status bit 5, alert flag in every status packet, torque
forced off).
"""

from __future__ import annotations

import contextlib
import os
import random
import select
import threading
import time
import tty
from dataclasses import dataclass, field
from functools import lru_cache

import mujoco
import numpy as np

from toddlerbot.actuation.catalogue import MotorModel, default_catalogue
from toddlerbot.actuation.model import ActuatorArrays, actuator_arrays, motor_torque
from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware import protocol as p
from toddlerbot.hardware.control_table import (
    ENTRIES,
    MODE_CURRENT_BASED_POSITION,
    MODE_EXTENDED_POSITION,
    MODE_POSITION,
    PULSES_PER_REV,
    TABLE_SIZE,
    Entry,
    decode,
    encode,
    pulses_to_rad,
    rad_s_to_velocity,
    rad_to_pulses,
    torque_to_load,
    traits,
)
from toddlerbot.robot.builder import build_model
from toddlerbot.robot.spec import RobotSpec

SUPPLY_VOLTAGE = 12.0
"""Default emulated supply voltage, V."""
LOAD_INERTIA = 0.002
"""Load inertia added to the armature of each motor in `SimplePlant`, kg*m^2."""
FIRMWARE_VERSION = 52
MAX_LAG = 0.05
"""Largest lag (s) of the hardware-in-the-loop simulation behind wall-clock time; beyond it, time is dropped
(reported by `HilPlant.realtime_factor`)."""


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
                    if not 0.0 <= values[key] <= 1.0:
                        raise ValueError("a probability must lie in [0, 1]")
                elif key in ("missing", "overload"):
                    values[key] = values.get(key, frozenset()) | {int(v) for v in value.split("+")}
                elif key == "voltage":
                    values[key] = float(value)
                elif key == "seed":
                    values[key] = int(value)
                else:
                    raise ValueError("unknown fault; expected drop, corrupt, missing, voltage, overload or seed")
            except ValueError as exc:
                raise FaultSpecError(f"fault {item!r}: {exc}") from None
        return cls(**values)


def _defaults(model: MotorModel, dxl_id: int) -> dict[str, int]:
    t = traits(model)
    values = {
        "model_number": model.model_number or 0, "firmware_version": FIRMWARE_VERSION, "id": dxl_id,
        "baud_rate": 1, "return_delay_time": 250, "operating_mode": MODE_POSITION,
        "max_voltage_limit": t.max_voltage_limit, "min_voltage_limit": t.min_voltage_limit, "pwm_limit": 885,
        "velocity_limit": 300, "max_position_limit": 4095, "min_position_limit": 0, "status_return_level": 2,
        "position_p_gain": 800, "position_d_gain": 0, "present_temperature": 30,
    }
    if t.current_sensing:
        values["current_limit"] = values["goal_current"] = 1193 if model.name.startswith("XM") else 1750
    return values


class EmulatedMotor:
    """One motor's control table and register semantics (no motion: a plant fills the present values)."""

    def __init__(self, dxl_id: int, name: str, model: MotorModel, mounting_offset: int) -> None:
        self.name = name
        self.model = model
        self.mounting_offset = mounting_offset
        """Reading (pulses) at motor angle 0 before the multi-turn count is dropped."""
        self.turn_offset = 0
        self.overloaded = False
        self.memory = bytearray(TABLE_SIZE)
        self.factory_reset(keep_id=False, dxl_id=dxl_id)

    # -- registers ---------------------------------------------------------------------------------------
    def entries(self) -> list[Entry]:
        current = traits(self.model).current_sensing
        return [e for e in ENTRIES.values() if current or not e.current_only]

    def get(self, name: str) -> int:
        e = ENTRIES[name]
        return decode(self.memory[e.address : e.address + e.size], e.signed)

    def set(self, name: str, value: int) -> None:
        e = ENTRIES[name]
        self.memory[e.address : e.address + e.size] = encode(value, e.size)

    @property
    def id(self) -> int:
        return self.memory[ENTRIES["id"].address]

    @property
    def torque_on(self) -> bool:
        return self.get("torque_enable") == 1

    def factory_reset(self, keep_id: bool, dxl_id: int = 1) -> None:
        dxl_id = self.id if keep_id else dxl_id
        self.memory[:] = bytes(TABLE_SIZE)
        for name, value in _defaults(self.model, dxl_id).items():
            self.set(name, value)
        self.turn_offset = 0
        self.overloaded_refresh()

    def overloaded_refresh(self) -> None:
        self.set("hardware_error_status", 0x20 if self.overloaded else 0)
        if self.overloaded:
            self.set("torque_enable", 0)

    def error_flags(self, voltage: float) -> int:
        status = 0x20 if self.overloaded else 0
        if voltage * 10 < self.get("min_voltage_limit") or voltage * 10 > self.get("max_voltage_limit"):
            status |= 0x01
        self.set("hardware_error_status", status)
        return p.ALERT if status else 0

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        if length < 1 or address + length > TABLE_SIZE:
            return p.ERR_ACCESS, b""
        return 0, bytes(self.memory[address : address + length])

    def write(self, address: int, data: bytes) -> int:
        """Validate the whole write first (nothing is written on error); returns the error number."""
        end = address + len(data)
        if not data or end > TABLE_SIZE:
            return p.ERR_ACCESS
        touched = [e for e in self.entries() if e.address < end and address < e.address + e.size]
        covered = sum(e.size for e in touched)
        if covered != len(data) or any(e.address < address or e.address + e.size > end for e in touched):
            return p.ERR_DATA_LENGTH if touched else p.ERR_ACCESS
        values = {e.name: decode(data[e.address - address : e.address - address + e.size], e.signed) for e in touched}
        for e in touched:
            if not e.writable:
                return p.ERR_ACCESS
            if e.eeprom and self.torque_on:
                return p.ERR_ACCESS
        mode = values.get("operating_mode")
        if mode is not None:
            allowed = {1, MODE_POSITION, MODE_EXTENDED_POSITION, 16}
            if traits(self.model).current_sensing:
                allowed |= {0, MODE_CURRENT_BASED_POSITION}
            if mode not in allowed:
                return p.ERR_DATA_RANGE
        if values.get("torque_enable", 0) not in (0, 1):
            return p.ERR_DATA_RANGE
        goal = values.get("goal_position")
        if goal is not None and abs(goal) > 1_048_575:
            return p.ERR_DATA_LIMIT
        for name in ("position_p_gain", "position_i_gain", "position_d_gain"):
            if values.get(name, 0) > 16383:
                return p.ERR_DATA_RANGE
        self.memory[address:end] = data
        if self.overloaded:
            self.set("torque_enable", 0)
        return 0


class SimplePlant:
    """Independent motors: inertia (armature + LOAD_INERTIA), the actuator model, MuJoCo-like passive terms."""

    def __init__(self, motors: list[EmulatedMotor]) -> None:
        self.motors = motors
        params = [m.model.actuator for m in motors]
        self.params = params
        self.inertia = np.array([a.armature + LOAD_INERTIA for a in params])
        self.damping = np.array([a.damping for a in params])
        self.friction = np.array([a.frictionloss for a in params])
        self.q = np.zeros(len(motors))
        self.qd = np.zeros(len(motors))
        self.tau = np.zeros(len(motors))
        self.dt = 0.001
        self._last = time.perf_counter()

    def start(self, lock: threading.Lock) -> None:
        self._last = time.perf_counter()

    def stop(self) -> None:
        pass

    def update(self) -> None:
        """Advance to the present wall-clock time (called under the bus lock before each instruction).

        At most 4 semi-implicit Euler steps per call (each <= 5 ms, stable for these gains and inertias);
        time beyond that is dropped, so an idle bus never delays an answer."""
        now = time.perf_counter()
        elapsed, self._last = now - self._last, now
        steps = min(int(elapsed / self.dt), 4)
        if steps:
            dt = min(elapsed / steps, 0.005)
            cmd = commands(self.motors, self.params)
            for _ in range(steps):
                tau = np.where(cmd.torque_on, motor_torque(cmd.q_target, self.q, self.qd, cmd.arrays), 0.0)
                tau = np.clip(tau, -cmd.tau_limit, cmd.tau_limit)
                passive = self.damping * self.qd + self.friction * np.tanh(self.qd / 0.01)
                self.qd += dt * (tau - passive) / self.inertia
                self.q += dt * self.qd
                self.tau = tau
        else:
            self._last -= elapsed
        publish(self.motors, self.q, self.qd, self.tau)


@dataclass
class Commands:
    torque_on: np.ndarray
    q_target: np.ndarray
    arrays: ActuatorArrays
    tau_limit: np.ndarray


def commands(motors: list[EmulatedMotor], params: list) -> Commands:
    """Targets (rad, motor angle) and gains from the control tables."""
    goal = np.array([m.get("goal_position") - m.mounting_offset - m.turn_offset - m.get("homing_offset")
                     for m in motors])
    kp = tuple(m.get("position_p_gain") for m in motors)
    kd = tuple(m.get("position_d_gain") for m in motors)
    tau_limit = np.full(len(motors), np.inf)
    for i, m in enumerate(motors):
        t = traits(m.model)
        if m.get("operating_mode") == MODE_CURRENT_BASED_POSITION:
            tau_limit[i] = abs(m.get("goal_current")) * t.current_unit_a * t.torque_per_amp
    return Commands(
        torque_on=np.array([m.torque_on for m in motors]), q_target=pulses_to_rad(goal),
        arrays=_arrays(tuple(params), kp, kd), tau_limit=tau_limit,
    )


@lru_cache(maxsize=8)
def _arrays(params: tuple, kp: tuple, kd: tuple) -> ActuatorArrays:
    return actuator_arrays(params, kp, kd)


def publish(motors: list[EmulatedMotor], q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> None:
    """Write present position/velocity/current into the control tables."""
    pulses = rad_to_pulses(q)
    vel = rad_s_to_velocity(qd)
    tick = int(time.perf_counter() * 1000) % 32768
    for i, m in enumerate(motors):
        m.set("present_position", int(pulses[i]) + m.mounting_offset + m.turn_offset + m.get("homing_offset"))
        m.set("present_velocity", int(vel[i]))
        m.set("present_current", torque_to_load(float(tau[i]), m.model))
        m.set("realtime_tick", tick)
        m.set("moving", int(abs(qd[i]) > 0.02))


class HilPlant:
    """The whole robot in MuJoCo (floating base, floor), motors driven by the actuator model every physics step.

    The simulation holds still (robot hanging on its stand) until the first motor's torque is enabled, then
    runs in real time in a background thread; `realtime_factor` reports how well it kept up.
    """

    def __init__(self, motors: list[EmulatedMotor], spec: RobotSpec) -> None:
        self.motors = motors
        self.params = [m.model.actuator for m in motors]
        self.model = build_model(spec, base="floating", scene=True)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_resetDataKeyframe(self.model, self.data, self.model.key("home").id)
        mujoco.mj_forward(self.model, self.data)
        joints = self.model.actuator_trnid[:, 0]
        self.qadr = self.model.jnt_qposadr[joints]
        self.vadr = self.model.jnt_dofadr[joints]
        self.torso = self.model.body("torso").id
        self.sim_time = 0.0
        self.wall_time = 0.0
        self.powered_min_height = np.inf
        """Lowest torso height (m) seen while any motor had torque on."""
        self.powered_min_upright = np.inf
        """Lowest torso uprightness seen while any motor had torque on."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock: threading.Lock | None = None
        self._publish()

    @property
    def realtime_factor(self) -> float:
        return self.sim_time / self.wall_time if self.wall_time > 0 else 1.0

    def torso_height(self) -> float:
        """Height of the torso frame above the floor, m."""
        return float(self.data.xpos[self.torso][2])

    def torso_uprightness(self) -> float:
        """z component of the torso's up axis in the world (1 = upright, 0 = lying)."""
        return float(self.data.xmat[self.torso][8])

    def _publish(self) -> None:
        publish(self.motors, self.data.qpos[self.qadr], self.data.qvel[self.vadr], self.data.ctrl.copy())

    def start(self, lock: threading.Lock) -> None:
        self._lock = lock
        self._thread = threading.Thread(target=self._run, name="hil-physics", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def update(self) -> None:
        pass  # the physics thread publishes

    def _run(self) -> None:
        assert self._lock is not None
        m, d = self.model, self.data
        dt = m.opt.timestep
        while not self._stop.is_set():
            with self._lock:
                started = any(mo.torque_on for mo in self.motors)
            if started:
                break
            time.sleep(0.002)
        t0 = time.perf_counter()
        lost = 0.0  # wall-clock time the simulation gave up on (host too slow)
        while not self._stop.is_set():
            self.wall_time = time.perf_counter() - t0
            behind = self.wall_time - lost - self.sim_time
            if behind > MAX_LAG:  # never run flat out to catch up: the bus must keep answering
                lost += behind - MAX_LAG
            if behind < dt:
                time.sleep(min(dt, 0.002))
                continue
            with self._lock:
                cmd = commands(self.motors, self.params)
            for _ in range(min(int(behind / dt), 10)):
                q, qd = d.qpos[self.qadr], d.qvel[self.vadr]
                tau = np.where(cmd.torque_on, motor_torque(cmd.q_target, q, qd, cmd.arrays), 0.0)
                d.ctrl[:] = np.clip(tau, -cmd.tau_limit, cmd.tau_limit)
                mujoco.mj_step(m, d)
                self.sim_time += dt
            if cmd.torque_on.any():
                self.powered_min_height = min(self.powered_min_height, self.torso_height())
                self.powered_min_upright = min(self.powered_min_upright, self.torso_uprightness())
            with self._lock:
                self._publish()
            time.sleep(0)  # let the serving thread answer between batches


@dataclass
class BusStats:
    packets_in: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    crc_errors: int = 0
    by_instruction: dict[int, int] = field(default_factory=dict)


class EmulatedBus:
    """The motors of a spec on one Protocol 2.0 bus: `handle` maps an instruction packet to the bytes sent back."""

    def __init__(
        self,
        spec: RobotSpec,
        hil: bool = False,
        faults: Faults | None = None,
        fast_sync_read: bool = True,
        offsets_seed: int = 0,
    ) -> None:
        self.spec = spec
        self.faults = faults or Faults()
        self.fast_sync_read = fast_sync_read
        self._rng = random.Random(self.faults.seed)
        catalogue = default_catalogue()
        offset_rng = random.Random(offsets_seed)
        self.motors = []
        for ms in spec.motors_by_id:
            motor = EmulatedMotor(ms.id, ms.joint, catalogue[ms.model], offset_rng.randrange(0, PULSES_PER_REV))
            motor.overloaded = ms.id in self.faults.overload
            motor.overloaded_refresh()
            self.motors.append(motor)
        self.lock = threading.Lock()
        self.stats = BusStats()
        self.plant: SimplePlant | HilPlant = HilPlant(self.motors, spec) if hil else SimplePlant(self.motors)
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
        (the last one is the packet's CRC). A motor that does not answer breaks the chain: the packet ends there."""
        n = len(ids)
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
                ready, _, _ = select.select([self.master], [], [], 0.05)
                if not ready:
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
