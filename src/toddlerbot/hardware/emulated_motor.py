"""An emulated Dynamixel X-series motor: its control table, factory defaults and register semantics."""

from __future__ import annotations

import time

from toddlerbot.actuation.catalogue import MotorModel
from toddlerbot.hardware import protocol as p
from toddlerbot.hardware.control_table import (
    ENTRIES,
    MODE_CURRENT_BASED_POSITION,
    MODE_EXTENDED_POSITION,
    MODE_POSITION,
    TABLE_SIZE,
    Entry,
    decode,
    encode,
    traits,
)

FIRMWARE_VERSION = 52


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
        self.last_heard = 0.0
        """time.perf_counter() of the last instruction packet this motor heard (Bus Watchdog)."""
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

    def watchdog_expire(self) -> None:
        """The Bus Watchdog expired: hold where it is (goal = present position), register -1, goals locked."""
        self.set("goal_position", self.get("present_position"))
        self.set("bus_watchdog", -1)

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
        if not 0 <= values.get("bus_watchdog", 0) <= 127:
            return p.ERR_DATA_RANGE
        if self.get("bus_watchdog") == -1 and ({"goal_position", "goal_current"} & values.keys()):
            return p.ERR_DATA_RANGE  # goal registers are read-only after the Bus Watchdog expired
        goal = values.get("goal_position")
        if goal is not None and abs(goal) > 1_048_575:
            return p.ERR_DATA_LIMIT
        for name in ("position_p_gain", "position_i_gain", "position_d_gain"):
            if values.get(name, 0) > 16383:
                return p.ERR_DATA_RANGE
        self.memory[address:end] = data
        if self.overloaded:
            self.set("torque_enable", 0)
        if values.get("torque_enable") == 1:
            self.last_heard = time.perf_counter()  # the watchdog counts from torque-on
        return 0
