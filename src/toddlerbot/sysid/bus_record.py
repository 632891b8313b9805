"""`sysid.record` on one motor of a real Dynamixel bus: the bus adapted to the recorder's `Servo`, opened,
configured and checked before the first run (the hardware layer, extra `[hw]`, is imported only here)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from toddlerbot.actuation.catalogue import MotorModel
from toddlerbot.sysid.excitation import Excitation
from toddlerbot.sysid.record import record
from toddlerbot.sysid.rigs import Rig

MIN_VOLTAGE_FRACTION = 0.75
"""Default supply floor, as a fraction of the motor model's rated voltage."""


class BusServo:
    """A `toddlerbot.sysid.record.Servo` over one motor of a ``DynamixelBus``."""

    def __init__(self, bus, motor) -> None:
        from toddlerbot.hardware import control_table as ct

        self.bus, self.motor, self.ct = bus, motor, ct

    def read(self) -> tuple[float, float, float, float]:
        state = self.bus.read_state()
        volts = self.bus.read(self.motor, "present_input_voltage", allow_alert=True) * self.ct.VOLT_PER_UNIT
        return float(self.ct.pulses_to_rad(state.position[0])), float(state.velocity[0]), float(state.torque[0]), volts

    def set_gains(self, kp: int, kd: int) -> None:
        self.bus.write_gains(np.array([kp]), np.array([kd]))

    def set_goal(self, position: float) -> None:
        self.bus.write_goal_positions(np.array([self.ct.rad_to_pulses(position)]))

    def set_torque(self, on: bool) -> None:
        self.bus.write(self.motor, "torque_enable", int(on), allow_alert=not on)
        self.bus.torque_enabled = on


def record_on_bus(port: str, motor_id: int, model: MotorModel, runs: list[Excitation], folder: Path, rig: Rig,
                  settle: float, baudrate: int, min_voltage: float | None = None,
                  progress: Callable[[str], None] | None = None) -> Path:
    """Record `runs` on motor `motor_id` (a `model`) of the bus on `port` into `folder`; refuses a supply below
    `min_voltage` (default: `MIN_VOLTAGE_FRACTION` of the model's rating). Returns the manifest's path."""
    from toddlerbot.hardware import control_table as ct
    from toddlerbot.hardware.driver import BusMotor, DynamixelBus

    bus_motor = BusMotor(motor_id, f"id{motor_id}", model, ct.OPERATING_MODES["extended_position"], runs[0].kp, 0,
                         0, 0, 0)
    floor = MIN_VOLTAGE_FRACTION * model.rated_voltage if min_voltage is None else min_voltage
    with DynamixelBus(port, [bus_motor], baudrate=baudrate, min_voltage=floor) as bus:
        bus.scan()
        bus.configure()
        bus.check_voltage()
        return record(BusServo(bus, bus_motor), runs, folder, model.name, rig, settle, progress=progress)
