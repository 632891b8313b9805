"""The Dynamixel X-series control table entries ToddlerBot uses, per-model traits, and every unit conversion.

Addresses and sizes are the Protocol 2.0 X-series control table (ROBOTIS e-Manual, e.g. the XM430-W210 and
2XL430-W250 pages); they are the same on every model the robot uses except that only current-sensing models
(XM430, XC330) have Current Limit / Goal Current and report Present Current at address 126 — the others
report Present Load (0.1 % of the maximum torque) there. Model numbers come from the motor catalogue
(``model_number`` in ``toddlerbot/actuation/motors.yaml``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from toddlerbot.actuation.catalogue import Catalogue, MotorModel, default_catalogue


@dataclass(frozen=True)
class Entry:
    name: str
    address: int
    size: int
    """Bytes: 1, 2 or 4 (little endian)."""
    writable: bool = True
    eeprom: bool = False
    """EEPROM entries refuse writes while torque is enabled."""
    signed: bool = False
    current_only: bool = False
    """Present only on current-sensing models."""


_ENTRIES = (
    Entry("model_number", 0, 2, writable=False, eeprom=True),
    Entry("firmware_version", 6, 1, writable=False, eeprom=True),
    Entry("id", 7, 1, eeprom=True),
    Entry("baud_rate", 8, 1, eeprom=True),
    Entry("return_delay_time", 9, 1, eeprom=True),
    Entry("drive_mode", 10, 1, eeprom=True),
    Entry("operating_mode", 11, 1, eeprom=True),
    Entry("homing_offset", 20, 4, eeprom=True, signed=True),
    Entry("max_voltage_limit", 32, 2, eeprom=True),
    Entry("min_voltage_limit", 34, 2, eeprom=True),
    Entry("pwm_limit", 36, 2, eeprom=True),
    Entry("current_limit", 38, 2, eeprom=True, current_only=True),
    Entry("velocity_limit", 44, 4, eeprom=True),
    Entry("max_position_limit", 48, 4, eeprom=True),
    Entry("min_position_limit", 52, 4, eeprom=True),
    Entry("torque_enable", 64, 1),
    Entry("led", 65, 1),
    Entry("status_return_level", 68, 1),
    Entry("hardware_error_status", 70, 1, writable=False),
    Entry("position_d_gain", 80, 2),
    Entry("position_i_gain", 82, 2),
    Entry("position_p_gain", 84, 2),
    Entry("feedforward_2nd_gain", 88, 2),
    Entry("feedforward_1st_gain", 90, 2),
    Entry("bus_watchdog", 98, 1, signed=True),
    Entry("goal_current", 102, 2, signed=True, current_only=True),
    Entry("goal_position", 116, 4, signed=True),
    Entry("realtime_tick", 120, 2, writable=False),
    Entry("moving", 122, 1, writable=False),
    Entry("present_current", 126, 2, writable=False, signed=True),
    Entry("present_velocity", 128, 4, writable=False, signed=True),
    Entry("present_position", 132, 4, writable=False, signed=True),
    Entry("present_input_voltage", 144, 2, writable=False),
    Entry("present_temperature", 146, 1, writable=False),
)
ENTRIES: dict[str, Entry] = {e.name: e for e in _ENTRIES}
TABLE_SIZE = 148
"""Bytes of control table the emulator models (addresses 0..147)."""

# Blocks the control cycle reads and writes in one transaction each.
STATE_BLOCK = (126, 10)
"""Present current/load (2) + present velocity (4) + present position (4)."""
GAINS_BLOCK = (80, 6)
"""Position D (2), I (2), P (2) gains."""

# Operating modes (address 11).
MODE_POSITION = 3
MODE_EXTENDED_POSITION = 4
MODE_CURRENT_BASED_POSITION = 5
OPERATING_MODES = {"extended_position": MODE_EXTENDED_POSITION, "current_based_position": MODE_CURRENT_BASED_POSITION}

# Hardware error status bits (address 70).
HW_ERROR_BITS = {0: "input voltage", 2: "overheating", 3: "motor encoder", 4: "electrical shock", 5: "overload"}

# Units.
PULSES_PER_REV = 4096
RAD_PER_PULSE = 2.0 * math.pi / PULSES_PER_REV
RAD_S_PER_VELOCITY_UNIT = 0.229 * 2.0 * math.pi / 60.0
"""Present velocity unit: 0.229 rev/min."""
VOLT_PER_UNIT = 0.1
BUS_WATCHDOG_UNIT_S = 0.02
"""Bus Watchdog (address 98) unit: 20 ms; 0 disables it, 1..127 arm it, -1 reads back after it expired."""
BUS_WATCHDOG_MAX = 127
EXTENDED_POSITION_RANGE = 1_048_575
"""Goal position range in extended position mode, pulses (+-256 turns)."""


@dataclass(frozen=True)
class ModelTraits:
    """Datasheet facts of one motor model that the control table depends on (ROBOTIS e-Manual)."""

    current_sensing: bool
    current_unit_a: float = 0.0
    """Present current / goal current unit, A (0 where the model reports load instead)."""
    torque_per_amp: float = 0.0
    """Stall torque / stall current at 12 V, N*m/A (current-sensing models)."""
    min_voltage_limit: int = 60
    """Factory Min Voltage Limit, 0.1 V."""
    max_voltage_limit: int = 160


_TRAITS = {
    "XC330-T288": ModelTraits(True, 0.001, 1.00 / 0.88, min_voltage_limit=55, max_voltage_limit=140),
    "XM430-W210": ModelTraits(True, 0.00269, 3.0 / 2.3, min_voltage_limit=95, max_voltage_limit=160),
    "XC430-T240BB": ModelTraits(False),
    "2XL430-W250": ModelTraits(False, max_voltage_limit=140),
    "2XC430-W250": ModelTraits(False),
    # XL330 (e-Manual): current in 1 mA units; stall torque / stall current at 5.0 V; voltage limits 3.5-7.0 V
    "XL330-M288-T": ModelTraits(True, 0.001, 0.52 / 1.47, min_voltage_limit=35, max_voltage_limit=70),
    "XL330-M077-T": ModelTraits(True, 0.001, 0.215 / 1.47, min_voltage_limit=35, max_voltage_limit=70),
}


def traits(model: MotorModel) -> ModelTraits:
    return _TRAITS[model.name]


@cache
def models_by_number(catalogue: Catalogue | None = None) -> dict[int, MotorModel]:
    catalogue = catalogue or default_catalogue()
    return {m.model_number: m for m in catalogue.models.values() if m.model_number is not None}


def model_name(number: int) -> str:
    model = models_by_number().get(number)
    return model.name if model else f"unknown model {number}"


# ---- conversions (the only place where Dynamixel units meet SI) ------------------------------------------
def pulses_to_rad(pulses: np.ndarray | int) -> np.ndarray:
    return np.asarray(pulses, dtype=float) * RAD_PER_PULSE


def rad_to_pulses(rad: np.ndarray | float) -> np.ndarray:
    return np.rint(np.asarray(rad, dtype=float) / RAD_PER_PULSE).astype(np.int64)


def velocity_to_rad_s(units: np.ndarray | int) -> np.ndarray:
    return np.asarray(units, dtype=float) * RAD_S_PER_VELOCITY_UNIT


def rad_s_to_velocity(rad_s: np.ndarray | float) -> np.ndarray:
    return np.rint(np.asarray(rad_s, dtype=float) / RAD_S_PER_VELOCITY_UNIT).astype(np.int64)


def load_to_torque(raw: int, model: MotorModel) -> float:
    """Address-126 reading -> estimated output torque, N*m (present current x torque constant, or load share of
    the stall torque for models without current sensing)."""
    t = traits(model)
    if t.current_sensing:
        return raw * t.current_unit_a * t.torque_per_amp
    return raw / 1000.0 * model.stall_torque_nm


def torque_to_load(torque: float, model: MotorModel) -> int:
    """Inverse of `load_to_torque` (used by the emulator), clipped to the register's range."""
    t = traits(model)
    raw = torque / (t.current_unit_a * t.torque_per_amp) if t.current_sensing else torque / model.stall_torque_nm * 1000
    return int(np.clip(round(raw), -32768, 32767))


def describe_hardware_error(status: int) -> str:
    names = [name for bit, name in HW_ERROR_BITS.items() if status & (1 << bit)]
    return ", ".join(names) if names else f"hardware error status 0x{status:02x}"


def encode(value: int, size: int) -> bytes:
    """Little-endian bytes of a (possibly negative) register value."""
    return int(value & ((1 << (8 * size)) - 1)).to_bytes(size, "little")


def decode(data: bytes | bytearray | list[int], signed: bool) -> int:
    return int.from_bytes(bytes(data), "little", signed=signed)
