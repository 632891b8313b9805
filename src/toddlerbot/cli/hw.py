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

from toddlerbot.cli.options import ImuOption, check_run_policy, duration, open_robot_imu, output_file, run_policy_names
from toddlerbot.cli.output import console, save_or_fallback
from toddlerbot.files import json_text
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import CONTROL_DT, FALL_TILT_RAD

app = typer.Typer(help="Real robot: Dynamixel bus emulator, scan, zero-point calibration.", no_args_is_help=True)

SpecOption = Annotated[Path | None, typer.Option("--spec", help="Robot spec YAML (default: packaged ToddlerBot v1).")]
VariantOption = Annotated[str | None, typer.Option("--variant", help="Spec variant of this robot, e.g. gripper.")]
MotorParamsOption = Annotated[list[Path] | None, typer.Option(
    "--motor-params", help="params.json from `toddlerbot sysid fit` (repeatable): fitted actuator parameters.")]
PortOption = Annotated[str, typer.Option("--port", help="Serial device of the bus, e.g. /dev/ttyUSB0.")]
BaudOption = Annotated[int, typer.Option("--baud", help="Bus baud rate.")]
MAX_CONTROL_DT = 0.1
"""Longest control period of `hw run`, s: a goal at least every 100 ms keeps well inside the 0.5 s Bus Watchdog."""
LatencyOption = Annotated[float, typer.Option("--latency-ms", help="USB-serial latency timer, ms: status packets "
                                              "are awaited 2 x this + 2 ms (raise it on a loaded machine).")]


def _description(spec_path: Path | None, variant: str | None, motor_params: list[Path] | None = None
                 ) -> RobotDescription:
    return RobotDescription.load(spec_path, variant, motor_params or [])


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
    variant: VariantOption = None,
    motor_params: MotorParamsOption = None,
) -> None:
    """Serve the robot's motors on a pseudo-terminal: prints the device path as the first line, then serves until
    interrupted (Ctrl-C, SIGTERM, SIGHUP), then prints one JSON line of statistics. With --hil the simulated
    robot's IMU is published too, as the BNO08x reports it (`hw run --imu emulator` reads it)."""
    from toddlerbot.hardware.driver import raise_on_stop_signals
    from toddlerbot.hardware.emulator import EmulatedBus, Faults, PtyServer
    from toddlerbot.hardware.imu_stream import ImuPublisher, imu_socket_path
    from toddlerbot.hardware.plant import HilPlant

    parsed = Faults.parse(faults or [])
    if write_calibration is not None:
        output_file(write_calibration, "--write-calibration")
    bus = EmulatedBus(_description(spec_path, variant, motor_params), hil=hil, faults=parsed,
                      fast_sync_read=not no_fast_sync_read, offsets_seed=offsets_seed)
    if write_calibration is not None:
        from toddlerbot.hardware.calibration import Calibration, save_calibration, spec_label

        offsets = {m.name: m.mounting_offset for m in bus.motors}
        save_calibration(Calibration("emulated", spec_label(bus.description), offsets, {}), write_calibration)
    server = PtyServer(bus)
    plant = bus.plant
    imu = (ImuPublisher(imu_socket_path(server.path), lambda: plant.imu_sample).start()
           if isinstance(plant, HilPlant) else None)
    raise_on_stop_signals()  # every stop signal ends serving, even a SIGINT a background shell job ignores
    try:
        print(server.path, flush=True)
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
        if imu is not None:
            imu.stop()
    report = {"packets": bus.stats.packets_in, "bytes_in": bus.stats.bytes_in, "bytes_out": bus.stats.bytes_out,
              "crc_errors": bus.stats.crc_errors}
    if isinstance(bus.plant, HilPlant):
        report |= {"sim_time": round(bus.plant.sim_time, 3), "realtime_factor": round(bus.plant.realtime_factor, 3),
                   "torso_height": round(bus.plant.torso_height(), 4),
                   "torso_upright": round(bus.plant.torso_uprightness(), 4),
                   "powered_min_torso_height": _finite(bus.plant.powered_min_height),
                   "powered_min_torso_upright": _finite(bus.plant.powered_min_upright),
                   "powered_torso_motion": _rounded(bus.plant.powered_motion()), "imu_reports": imu.reports}
    print(json_text(report), flush=True)


def _finite(value: float) -> float:
    """Rounded value (NaN, never measured, becomes JSON null)."""
    return round(value, 4) if np.isfinite(value) else value


def _rounded(motion: tuple[float, float, float] | None) -> dict | None:
    """The torso's planar motion while powered as JSON (dx, dy m; yaw rad), None if never powered."""
    return None if motion is None else dict(zip(("dx_m", "dy_m", "yaw_rad"), (round(v, 4) for v in motion),
                                                strict=True))


@app.command()
def scan(
    port: PortOption, baud: BaudOption = 2_000_000, spec_path: SpecOption = None, variant: VariantOption = None
) -> None:
    """Ping every motor of the spec, check model numbers, read voltage and positions (torque stays off)."""
    from toddlerbot.hardware.control_table import model_name
    from toddlerbot.hardware.driver import DynamixelBus, motors_of

    description = _description(spec_path, variant)
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

    description = _description(spec_path, variant)
    existing = load_calibration(output) if output.exists() else None
    output_file(output, "--output")
    cal = existing
    for g in group or list(GROUPS):
        ids = {m.id for m in group_motors(description, g)}
        with DynamixelBus(port, motors_of(description, ids), baudrate=baud) as bus:
            offsets = measure_offsets(bus)
        cal = merge(cal, robot, description, g, offsets, force=force, source=str(output))
        console.print(f"{g}: {len(offsets)} motors read")
    save_calibration(cal, output)
    console.print(f"wrote {output} ({len(cal.offsets)} of {description.n_motors} motors calibrated)")


@app.command()
def run(
    port: PortOption,
    calibration: Annotated[Path, typer.Option("--calibration", help="Per-robot calibration file.")],
    policy: Annotated[str, typer.Option("--policy", help=f"One of: {', '.join(run_policy_names())} (dp: a "
                                        "diffusion policy: --checkpoint, --camera, --variant gripper).")] = "stand",
    command: Annotated[str, typer.Option("--command", help="Velocity schedule 'time: vx,vy,yaw_rate; ...'.")] =
        "0:0,0,0",
    motion: Annotated[str | None, typer.Option("--motion", help="For --policy replay: a motion name or file.")] = None,
    weights: Annotated[Path | None, typer.Option("--weights", help="For --policy walk-rl: an exported policy "
                                                 "(.npz or .onnx from `toddlerbot rl export`), or a shipped one by "
                                                 "name: walk_rl (default) or walk_rl_gpu.")] = None,
    checkpoint: Annotated[Path | None, typer.Option("--checkpoint", help="For --policy dp: a checkpoint from "
                                                    "`dp train` or `dp export`.")] = None,
    camera: Annotated[str | None, typer.Option("--camera", help="For --policy dp: the head camera, a V4L2 device "
                                               "(/dev/video0) or a video file (played at its frame rate).")] = None,
    threads: Annotated[int, typer.Option("--threads", min=1, help="For --policy dp: CPU threads for torch.")] = 1,
    seconds: Annotated[float, typer.Option("--seconds", help="Duration, s (at most an hour).")] = 5.0,
    control_dt: Annotated[float, typer.Option("--dt", help=f"Control period, s (at most {MAX_CONTROL_DT:g}).")] \
        = CONTROL_DT,
    log: Annotated[Path | None, typer.Option("--log", help="Save the run log (.npz).")] = None,
    imu: ImuOption = "bno08x",
    baud: BaudOption = 2_000_000,
    latency_ms: LatencyOption = 16.0,
    spec_path: SpecOption = None,
    variant: VariantOption = None,
    motor_params: MotorParamsOption = None,
) -> None:
    """Run a policy on the real robot (or the emulator). Torque goes off at the end, on any error (a refused
    command included), on Ctrl-C, SIGTERM, SIGHUP and SIGQUIT; an error exits with code 2 and one line, a signal
    with 128 + its number, a fall (the IMU tilted past the simulator's threshold) with 1. A run that stops early
    keeps the steps so far: in --log, or, when the bus or a motor failed, in a temporary file whose name is
    printed."""
    from toddlerbot.hardware.calibration import load_calibration
    from toddlerbot.hardware.driver import BusInterrupt, HardwareError, raise_on_stop_signals, raise_pending_stop
    from toddlerbot.hardware.real_robot import RealRobot
    from toddlerbot.policies import make_policy
    from toddlerbot.runtime.commands import CommandSchedule
    from toddlerbot.runtime.runner import RunLogObserver, run_policy

    previous = raise_on_stop_signals()  # a stop signal at any moment, even before the bus opens, ends the run
    stack = ExitStack()  # the dp policy's worker and camera reader stop however the run ends
    run_log, pol, video = RunLogObserver(), None, None
    try:
        raise_pending_stop()  # a Ctrl-C during start-up that an import swallowed
        check_run_policy(policy)
        duration(seconds, "--seconds")
        # longer periods would leave the motors' 0.5 s Bus Watchdog waiting for the next goal
        duration(control_dt, "--dt", MAX_CONTROL_DT)
        duration(latency_ms, "--latency-ms", 1000.0, "milliseconds")  # the driver's bound on the latency timer
        if log is not None:
            output_file(log, "--log")
        description = _description(spec_path, variant, motor_params)
        cal = load_calibration(calibration, description)
        schedule = CommandSchedule.parse(command)
        robot = RealRobot(description, port, cal, control_dt=control_dt, baudrate=baud,
                          calibration_source=str(calibration), latency_ms=latency_ms)
        # bad weights, motions, checkpoints or cameras fail before the bus opens
        if policy == "dp":
            from toddlerbot.cli.dp_live import hw_dp_policy

            pol, video = hw_dp_policy(robot, checkpoint, camera, threads)
            stack.callback(pol.close)
            if video is not None:
                stack.callback(video.close)
        else:
            pol = make_policy(policy, robot, motion, weights)
        robot.imu = open_robot_imu(imu, port, f"policy {pol.name}" if pol.needs_imu else None)
        stack.callback(robot.imu.close)
        with robot:
            result = run_policy(robot, pol, schedule, seconds, log=run_log)
    except BaseException as exc:
        if len(run_log.recorder) and (log is not None or isinstance(exc, HardwareError)):
            partial = run_log.finish(robot, pol)
            save_or_fallback(partial.save, log, f"the log of the {len(run_log.recorder)} steps before the stop")
        if isinstance(exc, BusInterrupt):
            console.print(f"{policy}: stopped by {exc.args[0]}; torque is off", highlight=False)
            raise typer.Exit(128 + exc.signum) from None
        raise
    finally:
        stack.close()
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    steps = result.log.time.size
    error = np.abs(result.log.motor_pos - result.log.motor_target).max(axis=1)
    console.print(f"{policy}: {steps} steps at {steps / max(result.log.step_period.sum(), 1e-9):.0f} Hz; "
                  f"median largest tracking error {np.rad2deg(np.median(error)):.2f} deg")
    if policy == "dp":
        from toddlerbot.cli.dp_live import describe_status

        console.print(describe_status(pol.status), highlight=False)
        if video is not None and video.error:  # e.g. the USB camera was unplugged: the policy held meanwhile
            console.print(f"camera {camera}: stopped after {video.frames} frames ({video.error})", highlight=False)
    if log:
        save_or_fallback(result.log.save, log, "the run log")
    if result.fell:
        console.print(f"{policy}: fell at {result.fall_time:.2f} s (torso tilted past {FALL_TILT_RAD:g} rad by the "
                      "IMU); stopped, torque is off", highlight=False)
        raise typer.Exit(1)
    sys.stdout.flush()
