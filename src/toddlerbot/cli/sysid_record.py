"""`toddlerbot sysid record`: identification runs on a real motor through the Dynamixel driver."""

from __future__ import annotations

import enum
import json
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.cli.options import duration, within
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir
from toddlerbot.robot.safety import MAX_FIRMWARE_GAIN
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.excitation import PROFILES, SAMPLE_HZ, Excitation, excitation_set
from toddlerbot.sysid.logs import MAX_DURATION_S
from toddlerbot.sysid.rigs import Rig, parse_rig

RECORD_PROFILES = ("chirp", "steps", "sinusoids", "drop")
RECORD_KP = (100, 400)

Profile = enum.Enum("Profile", {name: name for name in PROFILES}, type=str)
"""The excitation profiles as typed choices (typer takes a list of enum members, not of Literal values)."""


def profile_names(profiles: list[Profile] | None, default: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(p.value for p in profiles) if profiles else default


def excitation_runs(profiles: tuple[str, ...], kp: tuple[int, ...], seconds: float, rate: float, amplitude: float,
                    center: float = 0.0) -> list[Excitation]:
    """`excitation_set` of option values, each checked first (a 1e9 s run would allocate terabytes)."""
    duration(seconds, "--duration", MAX_DURATION_S)
    within(rate, "--rate", 1.0, 1000.0, "Hz")
    within(amplitude, "--amplitude", 0.0, np.pi, "rad")
    within(center, "--center", -np.pi, np.pi, "rad")
    for gain in kp:
        within(gain, "--kp", 0, MAX_FIRMWARE_GAIN, "firmware units")
    return excitation_set(profiles, kp, seconds, rate, amplitude, center)


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


PortOption = Annotated[str, typer.Option("--port", help="Serial device of the Dynamixel bus, e.g. /dev/ttyUSB0.")]
MotorIdOption = Annotated[int, typer.Option("--id", min=0, max=252, help="Dynamixel id of the motor.")]
MotorOption = Annotated[str, typer.Option("--motor", help="Catalogue model or alias, e.g. XL330-M288 (checked "
                                          "against the model number the motor reports).")]
OutputOption = Annotated[Path, typer.Option("-o", "--output", help="Folder for the run CSVs and manifest.json.")]
RigOption = Annotated[str, typer.Option("--rig", help="pendulum, testbed, or a rig as JSON (as in a manifest).")]
ProfileOption = Annotated[list[Profile] | None, typer.Option(
    "--profile", help=f"Repeatable (default {', '.join(RECORD_PROFILES)}).")]
KpOption = Annotated[list[int] | None, typer.Option("--kp", help="Firmware kp values (repeatable; default 100, 400).")]
MinVoltageOption = Annotated[float | None, typer.Option(
    "--min-voltage", help="Refuse to run below this supply, V (default: 75 % of the model's rating).")]


def record_command(
    port: PortOption,
    motor_id: MotorIdOption,
    motor: MotorOption,
    output: OutputOption,
    rig: RigOption = "pendulum",
    mass: Annotated[float, typer.Option("--mass", help="Pendulum mass, kg.")] = 0.49,
    length: Annotated[float, typer.Option("--length", help="Pendulum length, m.")] = 0.10,
    load_inertia: Annotated[float | None, typer.Option("--load-inertia", help="Test-bed inertia, kg*m^2.")] = None,
    profile: ProfileOption = None,
    kp: KpOption = None,
    seconds: Annotated[float, typer.Option("--duration", help="Seconds per run.")] = 6.0,
    rate: Annotated[float, typer.Option("--rate", help="Sample rate, Hz.")] = SAMPLE_HZ,
    amplitude: Annotated[float, typer.Option("--amplitude", help="Goal amplitude, rad.")] = 0.5,
    settle: Annotated[float, typer.Option("--settle", help="Seconds to reach the first goal of each run.")] = 1.0,
    baudrate: Annotated[int, typer.Option("--baudrate", help="Bus baud rate.")] = 2_000_000,
    min_voltage: MinVoltageOption = None,
) -> None:
    """Play excitation profiles on one motor (torque-off drop included) and record position, velocity, torque
    estimate, supply voltage and torque state at the bus rate, as CSVs + manifest.json for `sysid fit`.
    Start with the rig at rest: the first reading (torque off) is q = 0."""
    from rich.progress import Progress

    from toddlerbot.sysid.bus_record import record_on_bus

    output_dir(output, "--output")
    duration(settle, "--settle", 60.0)
    model = default_catalogue()[motor]
    rig_obj = _rig(rig, mass, length, load_inertia)
    runs = excitation_runs(profile_names(profile, RECORD_PROFILES), tuple(kp or RECORD_KP), seconds, rate, amplitude)
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("recording", total=len(runs))
        manifest = record_on_bus(port, motor_id, model, runs, output, rig_obj, settle, baudrate, min_voltage,
                                 progress=lambda name: bar.update(task, advance=1, description=f"recording {name}"))
    console.print(f"wrote {len(runs)} runs and {manifest}")
