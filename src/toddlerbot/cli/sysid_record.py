"""`toddlerbot sysid record`: identification runs on a real motor through the Dynamixel driver."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from toddlerbot.actuation.catalogue import MotorModel, default_catalogue
from toddlerbot.cli.output import console
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.excitation import PROFILES, excitation_set
from toddlerbot.sysid.rigs import Rig, parse_rig

RECORD_PROFILES = ("chirp", "steps", "sinusoids", "drop")
RECORD_KP = (100, 400)


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


def _rig(text: str, mass: float, length: float, load_inertia: float | None) -> Rig:
    if text.lstrip().startswith("{"):
        try:
            return parse_rig(json.loads(text), "--rig")
        except json.JSONDecodeError as exc:
            raise SysIDError(f"--rig: not valid JSON ({exc})") from None
    raw: dict = {"type": text}
    if text == "pendulum":
        raw |= {"mass": mass, "length": length}
    elif text == "testbed":
        if load_inertia is None:
            raise SysIDError("--rig testbed needs --load-inertia (kg*m^2)")
        raw["load_inertia"] = load_inertia
    return parse_rig(raw, "--rig")


def record_command(
    port: Annotated[str, typer.Option("--port", help="Serial device of the Dynamixel bus, e.g. /dev/ttyUSB0.")],
    motor_id: Annotated[int, typer.Option("--id", min=0, max=252, help="Dynamixel id of the motor.")],
    motor: Annotated[str, typer.Option("--motor", help="Catalogue model or alias, e.g. XL330-M288 (checked "
                                       "against the model number the motor reports).")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Folder for the run CSVs and manifest.json.")],
    rig: Annotated[str, typer.Option("--rig", help="pendulum, testbed, or a rig as JSON (as in a manifest).")]
    = "pendulum",
    mass: Annotated[float, typer.Option("--mass", help="Pendulum mass, kg.")] = 0.49,
    length: Annotated[float, typer.Option("--length", help="Pendulum length, m.")] = 0.10,
    load_inertia: Annotated[float | None, typer.Option("--load-inertia", help="Test-bed inertia, kg*m^2.")] = None,
    profile: Annotated[list[str] | None, typer.Option(
        "--profile", help=f"Repeatable; {', '.join(PROFILES)} (default {', '.join(RECORD_PROFILES)}).")] = None,
    kp: Annotated[list[int] | None, typer.Option("--kp", help="Firmware kp values (repeatable; default 100, 400).")]
    = None,
    duration: Annotated[float, typer.Option("--duration", help="Seconds per run.")] = 6.0,
    rate: Annotated[float, typer.Option("--rate", help="Sample rate, Hz.")] = 200.0,
    amplitude: Annotated[float, typer.Option("--amplitude", help="Goal amplitude, rad.")] = 0.5,
    settle: Annotated[float, typer.Option("--settle", help="Seconds to reach the first goal of each run.")] = 1.0,
    baudrate: Annotated[int, typer.Option("--baudrate", help="Bus baud rate.")] = 2_000_000,
    min_voltage: Annotated[float | None, typer.Option(
        "--min-voltage", help="Refuse to run below this supply, V (default: 75 % of the model's rating).")] = None,
) -> None:
    """Play excitation profiles on one motor (torque-off drop included) and record position, velocity, torque
    estimate, supply voltage and torque state at the bus rate, as CSVs + manifest.json for `sysid fit`.
    Start with the rig at rest: the first reading (torque off) is q = 0."""
    from rich.progress import Progress

    from toddlerbot.hardware import control_table as ct
    from toddlerbot.hardware.driver import BusMotor, DynamixelBus
    from toddlerbot.sysid.record import record

    model: MotorModel = default_catalogue()[motor]
    rig_obj = _rig(rig, mass, length, load_inertia)
    for name in profile or []:
        if name not in PROFILES:
            raise SysIDError(f"--profile: unknown profile {name!r}; expected one of {', '.join(PROFILES)}")
    if not 1.0 <= rate <= 1000.0 or duration <= 0:
        raise SysIDError(f"--rate must be 1-1000 Hz and --duration > 0 s, got {rate} Hz, {duration} s")
    runs = excitation_set(tuple(profile or RECORD_PROFILES), tuple(kp or RECORD_KP), duration, rate, amplitude)
    bus_motor = BusMotor(motor_id, f"id{motor_id}", model, ct.OPERATING_MODES["extended_position"], runs[0].kp, 0,
                         0, 0, 0)
    floor = 0.75 * model.rated_voltage if min_voltage is None else min_voltage
    with DynamixelBus(port, [bus_motor], baudrate=baudrate, min_voltage=floor) as bus:
        bus.scan()
        bus.configure()
        bus.check_voltage()
        with Progress(console=console, transient=True) as bar:
            task = bar.add_task("recording", total=len(runs))
            manifest = record(BusServo(bus, bus_motor), runs, output, model.name, rig_obj, settle,
                              progress=lambda name: bar.update(task, advance=1, description=f"recording {name}"))
    console.print(f"wrote {len(runs)} runs and {manifest}")
