"""`toddlerbot hw ...`: Dynamixel bus emulator, bus scan, zero-point calibration, policies on the real robot."""

from __future__ import annotations

import signal
import sys
from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from toddlerbot.cli.options import (
    AsymmetricOption,
    ControlHzOption,
    ImuOption,
    MocapOption,
    MotorParamsOption,
    OnFallOption,
    RobotOptions,
    SpecOption,
    StepInPlaceOption,
    TerrainOption,
    TerrainSeedOption,
    VariantOption,
    WeightsOption,
    check_run_policy,
    duration,
    seed_option,
    stand_option,
    symmetric_option,
    within,
)
from toddlerbot.cli.output import console, save_or_fallback
from toddlerbot.cli.output_paths import output_file
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import json_text
from toddlerbot.policies import policy_names
from toddlerbot.robot.interface import CONTROL_HZ, FALL_TILT_RAD

app = typer.Typer(help="Real robot: Dynamixel bus emulator, scan, zero-point calibration.", no_args_is_help=True)

PortOption = Annotated[str, typer.Option("--port", help="Serial device of the bus, e.g. /dev/ttyUSB0.")]
BaudOption = Annotated[int, typer.Option("--baud", help="Bus baud rate.")]
MAX_CONTROL_DT = 0.1
"""Longest control period of `hw run`, s: a goal at least every 100 ms keeps well inside the 0.5 s Bus Watchdog."""
LatencyOption = Annotated[float, typer.Option("--latency-ms", help="USB-serial latency timer, ms: status packets "
                                              "are awaited 2 x this + 2 ms (raise it on a loaded machine).")]


@app.command()
def emulate(
    hil: Annotated[bool, typer.Option("--hil", help="Hardware in the loop: MuJoCo produces the motion.")] = False,
    faults: Annotated[list[str] | None, typer.Option("--faults", help="drop=P, corrupt=P, missing=ID[+ID], "
                                                     "voltage=V, overload=ID[+ID], seed=N (repeatable).")] = None,
    no_fast_sync_read: Annotated[bool, typer.Option("--no-fast-sync-read", help="Emulate firmware "
                                                    "without Fast Sync Read.")] = False,
    offsets_seed: Annotated[int, seed_option("Seed of the hidden mounting offsets.", "--offsets-seed")] = 0,
    write_calibration: Annotated[Path | None, typer.Option("--write-calibration", help="Also write the emulated "
                                                           "robot's true zero offsets as a calibration file.")] = None,
    spec_path: SpecOption = None,
    variant: VariantOption = None,
    motor_params: MotorParamsOption = None,
    kick: Annotated[list[str] | None, typer.Option("--kick", help="With --hil: push the simulated robot, TIME:SPEED "
                                                   "or TIME:SPEED@DEGREES (s after torque first comes on, m/s, from "
                                                   "its heading: 0 forward, 180 backwards; repeatable).")] = None,
    kick_seed: Annotated[int, seed_option("Seed of the directions of --kick without @DEGREES.", "--kick-seed")] = 0,
    terrain: TerrainOption = None,
    terrain_seed: TerrainSeedOption = 0,
) -> None:
    """Serve the robot's motors on a pseudo-terminal: prints the device path as the first line, then serves until
    interrupted (Ctrl-C, SIGTERM, SIGHUP), then prints one JSON line of statistics. With --hil the simulated
    robot's IMU is published too, as the BNO08x reports it (`hw run --imu emulator` reads it), and --terrain is
    the ground it stands on."""
    from toddlerbot.hardware.emulator import EmulatedBus, Faults
    from toddlerbot.hardware.hil_kicks import parse_kicks
    from toddlerbot.hardware.serve import serve_until_stopped, write_true_calibration
    from toddlerbot.sim.terrain import parse_terrain

    parsed = Faults.parse(faults or [])
    robot = RobotOptions.of(spec_path, variant, motor_params)
    if write_calibration is not None:
        output_file(write_calibration, "--write-calibration", robot.files)
    bus = EmulatedBus(robot.description(), hil=hil, faults=parsed, fast_sync_read=not no_fast_sync_read,
                      offsets_seed=offsets_seed, kicks=parse_kicks(kick or [], kick_seed),
                      terrain=None if terrain is None else parse_terrain(terrain), terrain_seed=terrain_seed)
    if write_calibration is not None:
        write_true_calibration(bus, write_calibration)
    report = serve_until_stopped(bus, lambda path: print(path, flush=True))
    print(json_text(report), flush=True)


@app.command()
def scan(
    port: PortOption, baud: BaudOption = 2_000_000, spec_path: SpecOption = None, variant: VariantOption = None
) -> None:
    """Ping every motor of the spec, check model numbers, read voltage and positions (torque stays off)."""
    from toddlerbot.hardware.control_table import model_name
    from toddlerbot.hardware.driver import DynamixelBus, motors_of

    description = RobotOptions.of(spec_path, variant).description()
    with DynamixelBus(port, motors_of(description), baudrate=baud) as bus:
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
    variant: VariantOption = None,
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

    description = RobotOptions.of(spec_path, variant).description()
    existing = load_calibration(output) if output.exists() else None  # updated in place: its other groups are kept
    output_file(output, "--output", [spec_path])
    cal = existing
    for g in group or list(GROUPS):
        ids = {m.id for m in group_motors(description, g)}
        with DynamixelBus(port, motors_of(description, ids), baudrate=baud) as bus:
            offsets = measure_offsets(bus)
        cal = merge(cal, robot, description, g, offsets, force=force, source=str(output))
        console.print(f"{g}: {len(offsets)} motors read")
    save_calibration(cal, output)
    console.print(f"wrote {output} ({len(cal.offsets)} of {description.n_motors} motors calibrated)")


CalibrationOpt = Annotated[Path, typer.Option("--calibration", help="Per-robot calibration file.")]
HwPolicyOpt = Annotated[str, typer.Option("--policy", help=f"One of: {', '.join(policy_names())} (dp: a "
                                          "diffusion policy: --checkpoint, --camera, --variant gripper).")]
HwCommandOpt = Annotated[str, typer.Option("--command", help="Velocity schedule 'time: vx,vy,yaw_rate; ...'.")]
MotionOpt = Annotated[str | None, typer.Option("--motion", help="For --policy replay: a motion name or file.")]
CheckpointOpt = Annotated[Path | None, typer.Option("--checkpoint", help="For --policy dp: a checkpoint from "
                                                    "`dp train` or `dp export`.")]
CameraOpt = Annotated[str | None, typer.Option("--camera", help="For --policy dp: the head camera, a V4L2 device "
                                               "(/dev/video0) or a video file (played at its frame rate).")]
ThreadsOpt = Annotated[int | None, typer.Option("--threads", min=1, help="For --policy dp: CPU threads for torch "
                                                 "(default 1).")]
SecondsOpt = Annotated[float, typer.Option("--seconds", help="Duration, s (at most an hour).")]
DtOpt = Annotated[float | None, typer.Option("--dt", help="Deprecated (0.2.0): the control period, s; use "
                                                            "--control-hz.")]
LogOpt = Annotated[Path | None, typer.Option("--log", help="Save the run log (.npz).")]


@app.command()
def run(port: PortOption, calibration: CalibrationOpt, policy: HwPolicyOpt = "stand", command: HwCommandOpt = "0:0,0,0",
        motion: MotionOpt = None, weights: WeightsOption = None, checkpoint: CheckpointOpt = None,
        camera: CameraOpt = None, threads: ThreadsOpt = None, seconds: SecondsOpt = 5.0,
        control_hz: ControlHzOption = None, control_dt: DtOpt = None,
        log: LogOpt = None, imu: ImuOption = "bno08x", baud: BaudOption = 2_000_000, latency_ms: LatencyOption = 16.0,
        spec_path: SpecOption = None, variant: VariantOption = None, motor_params: MotorParamsOption = None,
        asymmetric: AsymmetricOption = False, mocap: MocapOption = "none", on_fall: OnFallOption = "stop",
        step_in_place: StepInPlaceOption = False) -> None:
    """Run a policy on the real robot (or the emulator). Torque goes off at the end, on any error (a refused
    command included), on Ctrl-C, SIGTERM, SIGHUP and SIGQUIT; an error exits with code 2 and one line, a signal
    with 128 + its number, a fall (the IMU tilted past the simulator's threshold) with 1. A run that stops early
    keeps the steps so far: in --log, or, when the bus or a motor failed, in a temporary file whose name is
    printed."""
    from toddlerbot.hardware.driver import BusInterrupt, raise_on_stop_signals, raise_pending_stop
    from toddlerbot.sessions.robot import robot_session

    previous = raise_on_stop_signals()  # a stop signal at any moment, even before the bus opens, ends the run
    stack = ExitStack()  # the dp policy's worker and camera reader stop however the run ends
    try:
        raise_pending_stop()  # a Ctrl-C during start-up that an import swallowed
        options = RobotOptions.of(spec_path, variant, motor_params)
        control_dt = _check_run(policy, seconds, control_hz, control_dt, latency_ms, log,
                                [calibration, motion, weights, checkpoint, *options.files])
        session = stack.enter_context(robot_session(
            options.description(), port, calibration, policy, command, seconds, control_dt, baud, latency_ms, imu,
            mocap, on_fall, motion=motion, weights=weights, checkpoint=checkpoint, camera=camera, threads=threads,
            **symmetric_option(policy, asymmetric), **stand_option(policy, step_in_place)))
        result = session.run(log, lambda partial: save_or_fallback(
            partial.save, log, f"the log of the {partial.time.size} steps before the stop"))
    except BusInterrupt as exc:
        console.print(f"{policy}: stopped by {exc.args[0]}; torque is off", highlight=False)
        raise typer.Exit(128 + exc.signum) from None
    finally:
        stack.close()
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    _report_run(policy, result, session.policy, log, session.robot.bus)


def _check_run(policy: str, seconds: float, control_hz: float | None, control_dt: float | None,
               latency_ms: float, log: Path | None, inputs: list) -> float:
    """The control period of the run, s, once every option is shown usable (`--dt`, deprecated, says so)."""
    check_run_policy(policy)
    duration(seconds, "--seconds")
    control_dt = _control_period(control_hz, control_dt)
    duration(latency_ms, "--latency-ms", 1000.0, "milliseconds")  # the driver's bound on the latency timer
    if log is not None:
        output_file(log, "--log", inputs)
    return control_dt


def _control_period(control_hz: float | None, control_dt: float | None) -> float:
    """The control period from --control-hz (default the 50 Hz rate), or from the deprecated --dt (with a
    warning); longer than `MAX_CONTROL_DT` would leave the motors' 0.5 s Bus Watchdog waiting for the next goal."""
    if control_dt is None:
        within(CONTROL_HZ if control_hz is None else control_hz, "--control-hz", 1.0 / MAX_CONTROL_DT, 1000.0, "Hz")
        return 1.0 / (CONTROL_HZ if control_hz is None else control_hz)
    if control_hz is not None:
        raise ToddlerbotError("--dt and --control-hz both give the control rate; keep --control-hz")
    duration(control_dt, "--dt", MAX_CONTROL_DT)
    console.print(f"[yellow]warning:[/] --dt is deprecated; use --control-hz {1.0 / control_dt:g}", highlight=False)
    return control_dt


def _report_run(policy: str, result, pol, log: Path | None, bus) -> None:
    """Print the run's rate, tracking and what the bus lost, save the log; a fall exits 1."""
    steps = result.log.time.size
    error = np.abs(result.log.motor_pos - result.log.motor_target).max(axis=1)
    console.print(f"{policy}: {steps} steps at {steps / max(result.log.step_period.sum(), 1e-9):.0f} Hz; "
                  f"median largest tracking error {np.rad2deg(np.median(error)):.2f} deg")
    console.print(f"bus {bus.port_name}: {bus.counters.describe()}", highlight=False)
    if pol.status is not None:  # e.g. dp's inference, and how its camera stopped if it did
        console.print(pol.status.describe(), highlight=False)
    if result.falls:
        console.print(f"{policy}: {result.falls} falls, got up from {result.recoveries}", highlight=False)
    if np.all(np.isfinite(result.log.base_pos)):  # motion capture watched the run
        from toddlerbot.runtime.summary import summarize

        summary = summarize(result.log, result.fell, result.fall_time)
        console.print(f"{policy} by motion capture: {summary.motion_text()}", highlight=False)
    if log:
        save_or_fallback(result.log.save, log, "the run log")
    if result.fell:
        console.print(f"{policy}: fell at {result.fall_time:.2f} s (torso tilted past {FALL_TILT_RAD:g} rad by the "
                      "IMU); stopped, torque is off", highlight=False)
        raise typer.Exit(1)
    sys.stdout.flush()
