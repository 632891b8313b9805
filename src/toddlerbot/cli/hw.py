"""`toddlerbot hw ...`: Dynamixel bus emulator, bus scan, zero-point calibration, policies on the real robot."""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from toddlerbot.cli.output import console
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import RobotSpec, load_spec

app = typer.Typer(help="Real robot: Dynamixel bus emulator, scan, zero-point calibration.", no_args_is_help=True)

SpecOption = Annotated[Path | None, typer.Option("--spec", help="Robot spec YAML (default: packaged ToddlerBot v1).")]
GripperOption = Annotated[bool, typer.Option("--gripper", help="The robot has the gripper variant.")]
PortOption = Annotated[str, typer.Option("--port", help="Serial device of the bus, e.g. /dev/ttyUSB0.")]
BaudOption = Annotated[int, typer.Option("--baud", help="Bus baud rate.")]


def _spec(spec_path: Path | None, gripper: bool) -> RobotSpec:
    spec = load_spec(spec_path)
    return spec.with_variant("gripper") if gripper else spec


@app.command()
def emulate(
    hil: Annotated[bool, typer.Option("--hil", help="Hardware in the loop: MuJoCo produces the motion.")] = False,
    faults: Annotated[list[str] | None, typer.Option("--faults", help="drop=P, corrupt=P, missing=ID[+ID], "
                                                     "voltage=V, overload=ID[+ID], seed=N (repeatable).")] = None,
    no_fast_sync_read: Annotated[bool, typer.Option("--no-fast-sync-read", help="Emulate firmware "
                                                    "without Fast Sync Read.")] = False,
    offsets_seed: Annotated[int, typer.Option("--offsets-seed", help="Seed of the hidden mounting offsets.")] = 0,
    write_calibration: Annotated[Path | None, typer.Option("--write-calibration", help="Also write the emulated "
                                                           "robot's true zero offsets as a calibration file.")] = None,
    spec_path: SpecOption = None,
    gripper: GripperOption = False,
) -> None:
    """Serve the spec's motors on a pseudo-terminal: prints the device path as the first line, then serves until
    interrupted (Ctrl-C/SIGTERM), then prints one JSON line of statistics."""
    from toddlerbot.hardware.emulator import EmulatedBus, Faults, PtyServer
    from toddlerbot.hardware.plant import HilPlant

    parsed = Faults.parse(faults or [])
    bus = EmulatedBus(_spec(spec_path, gripper), hil=hil, faults=parsed, fast_sync_read=not no_fast_sync_read,
                      offsets_seed=offsets_seed)
    if write_calibration is not None:
        from toddlerbot.hardware.calibration import Calibration, save_calibration, spec_label

        offsets = {m.name: m.mounting_offset for m in bus.motors}
        save_calibration(Calibration("emulated", spec_label(bus.spec), offsets, {}), write_calibration)
    server = PtyServer(bus)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        print(server.path, flush=True)
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    report = {"packets": bus.stats.packets_in, "bytes_in": bus.stats.bytes_in, "bytes_out": bus.stats.bytes_out,
              "crc_errors": bus.stats.crc_errors}
    if isinstance(bus.plant, HilPlant):
        report |= {"sim_time": round(bus.plant.sim_time, 3), "realtime_factor": round(bus.plant.realtime_factor, 3),
                   "torso_height": round(bus.plant.torso_height(), 4),
                   "torso_upright": round(bus.plant.torso_uprightness(), 4),
                   "powered_min_torso_height": _finite(bus.plant.powered_min_height),
                   "powered_min_torso_upright": _finite(bus.plant.powered_min_upright)}
    print(json.dumps(report), flush=True)


def _finite(value: float) -> float | None:
    """Rounded value, or None (JSON null) if never measured."""
    return round(value, 4) if np.isfinite(value) else None


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


@app.command()
def scan(
    port: PortOption, baud: BaudOption = 2_000_000, spec_path: SpecOption = None, gripper: GripperOption = False
) -> None:
    """Ping every motor of the spec, check model numbers, read voltage and positions (torque stays off)."""
    from toddlerbot.hardware.control_table import model_name
    from toddlerbot.hardware.driver import DynamixelBus, motors_of

    spec = _spec(spec_path, gripper)
    with DynamixelBus(port, motors_of(spec), baudrate=baud) as bus:
        found = bus.scan()
        voltage = bus.check_voltage()
        state = bus.read_state()
    table = Table("id", "motor", "model", "position [pulse]", "velocity [rad/s]")
    for k, m in enumerate(bus.motors):
        table.add_row(str(m.id), m.name, model_name(found[m.id]), str(state.position[k]), f"{state.velocity[k]:.3f}")
    console.print(table)
    console.print(f"{len(found)} motors OK, supply {voltage:.1f} V, "
                  f"{'Fast Sync Read' if bus.fast_sync_read else 'Sync Read'} available")


@app.command()
def calibrate(
    port: PortOption,
    output: Annotated[Path, typer.Option("-o", "--output", help="Per-robot calibration file (YAML).")],
    robot: Annotated[str, typer.Option("--robot", help="Name of this physical robot, e.g. toddlerbot-07.")],
    group: Annotated[list[str] | None, typer.Option("--group", help="arm, neck, hip or ankle (repeatable; "
                                                    "default: all).")] = None,
    force: Annotated[bool, typer.Option("--force", help="Accept offsets far from the existing file's.")] = False,
    baud: BaudOption = 2_000_000,
    spec_path: SpecOption = None,
    gripper: GripperOption = False,
) -> None:
    """Zero-point calibration: with a group's jigs clicked in, read its motors (torque off) and store the offsets."""
    from toddlerbot.hardware.calibration import (
        GROUPS,
        group_motors,
        load_calibration,
        measure_offsets,
        merge,
        save_calibration,
    )
    from toddlerbot.hardware.driver import DynamixelBus, motors_of

    spec = _spec(spec_path, gripper)
    existing = load_calibration(output) if output.exists() else None
    cal = existing
    for g in group or list(GROUPS):
        ids = {m.id for m in group_motors(spec, g)}
        with DynamixelBus(port, motors_of(spec, ids), baudrate=baud) as bus:
            offsets = measure_offsets(bus)
        cal = merge(cal, robot, spec, g, offsets, force=force, source=str(output))
        console.print(f"{g}: {len(offsets)} motors read")
    save_calibration(cal, output)
    console.print(f"wrote {output} ({len(cal.offsets)} of {len(spec.motors)} motors calibrated)")


@app.command()
def run(
    port: PortOption,
    calibration: Annotated[Path, typer.Option("--calibration", help="Per-robot calibration file.")],
    policy: Annotated[str, typer.Option("--policy", help="stand, replay or walk-zmp (as in `sim run`).")] = "stand",
    command: Annotated[str, typer.Option("--command", help="Velocity schedule 'time: vx,vy,yaw_rate; ...'.")] =
        "0:0,0,0",
    motion: Annotated[str | None, typer.Option("--motion", help="For --policy replay: a motion name or file.")] = None,
    seconds: Annotated[float, typer.Option("--seconds", help="Duration, s.")] = 5.0,
    control_dt: Annotated[float, typer.Option("--dt", help="Control period, s.")] = 0.02,
    log: Annotated[Path | None, typer.Option("--log", help="Save the run log (.npz).")] = None,
    baud: BaudOption = 2_000_000,
    spec_path: SpecOption = None,
    gripper: GripperOption = False,
) -> None:
    """Run a policy on the real robot (or the emulator); torque off at the end, on Ctrl-C and on any error."""
    from toddlerbot.hardware.calibration import load_calibration
    from toddlerbot.hardware.real_robot import RealRobot
    from toddlerbot.policies import make_policy
    from toddlerbot.runtime.commands import CommandSchedule
    from toddlerbot.runtime.runner import run_policy

    spec = _spec(spec_path, gripper)
    cal = load_calibration(calibration, spec)
    schedule = CommandSchedule.parse(command)
    description = RobotDescription(spec)
    with RealRobot(description, port, cal, control_dt=control_dt, baudrate=baud,
                   calibration_source=str(calibration)) as robot:
        result = run_policy(robot, make_policy(policy, robot, motion), schedule, seconds)
    steps = result.log.time.size
    error = np.abs(result.log.motor_pos - result.log.motor_target).max(axis=1)
    console.print(f"{policy}: {steps} steps at {steps / max(result.log.step_period.sum(), 1e-9):.0f} Hz; "
                  f"median largest tracking error {np.rad2deg(np.median(error)):.2f} deg")
    if log:
        result.log.save(log)
        console.print(f"wrote {log}")
    sys.stdout.flush()
