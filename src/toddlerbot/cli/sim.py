"""`toddlerbot sim ...`: run a policy on the simulated robot, render it, summarise and plot run logs."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import (
    AsymmetricOption,
    ControlHzOption,
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
    positive,
    seed_option,
    stand_option,
    symmetric_option,
)
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir, output_file
from toddlerbot.cli.progress import RunProgress
from toddlerbot.cli.sim_compare import compare_command
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_text, json_text
from toddlerbot.policies import policy_names
from toddlerbot.robot.interface import CONTROL_HZ
from toddlerbot.sim.terrain import parse_terrain

app = typer.Typer(help="Simulate ToddlerBot in MuJoCo: walk, stand, replay motions; render and plot runs.",
                  no_args_is_help=True)
app.command("compare")(compare_command)


PolicyOpt = Annotated[str, typer.Option("--policy", help=f"One of: {', '.join(policy_names())}.")]
CommandOpt = Annotated[str | None, typer.Option(
    "--command", help="Velocity schedule 'time: vx,vy,yaw_rate; ...' (s: m/s, m/s, rad/s), e.g. "
    "'0:0.1,0,0; 5:0,0,0.3'. Default: the policy's demo command (walk-zmp: 0.1 m/s forward), else zero.")]
CommandFileOpt = Annotated[Path | None, typer.Option("--command-file", help="Schedule file (one entry per line); "
                                                     "overrides --command.")]
MotionOpt = Annotated[str | None, typer.Option("--motion", help="For --policy replay: squat, wave, look_around or a "
                                               "motion YAML file.")]
SecondsOpt = Annotated[float, typer.Option("--seconds", help="Duration, s (replay stops at the motion's end).")]
RealtimeOpt = Annotated[bool, typer.Option("--realtime", help="Lock the loop to wall-clock time.")]
VideoOpt = Annotated[Path | None, typer.Option("--video", help="Write an MP4 from the tracking camera.")]
SnapshotOpt = Annotated[Path | None, typer.Option("--snapshot", help="Write a PNG of the last frame.")]
CameraOpt = Annotated[str, typer.Option("--camera", help="perspective, side, front, top or head_camera.")]
ViewerOpt = Annotated[bool, typer.Option("--viewer", help="Open the interactive MuJoCo viewer (needs a display; "
                                         "implies --realtime).")]
LogOpt = Annotated[Path | None, typer.Option("--log", help="Save the run log (.npz).")]
SummaryOpt = Annotated[Path | None, typer.Option("--summary-json", help="Write the summary as JSON.")]
TaskOpt = Annotated[str | None, typer.Option("--task", help="Run in a manipulation task's scene (pick, wagon: the "
                                             "gripper variant; the head camera as the camera of --policy dp).")]
CheckpointOpt = Annotated[Path | None, typer.Option("--checkpoint", help="For --policy dp: a checkpoint from "
                                                    "`dp train`/`dp export` (default: the one shipped for --task).")]
SeedOpt = Annotated[int, seed_option(help="For --task: scene seed (the cube's pose).")]
ThreadsOpt = Annotated[int | None, typer.Option("--threads", min=1, help="For --policy dp: CPU threads for torch "
                                                 "(default 1).")]


@app.command()
def run(policy: PolicyOpt = "walk-zmp", command: CommandOpt = None, command_file: CommandFileOpt = None,
        motion: MotionOpt = None, weights: WeightsOption = None, seconds: SecondsOpt = 10.0,
        control_hz: ControlHzOption = CONTROL_HZ, realtime: RealtimeOpt = False, video: VideoOpt = None,
        snapshot: SnapshotOpt = None, camera: CameraOpt = "perspective", viewer: ViewerOpt = False,
        log: LogOpt = None, summary_json: SummaryOpt = None, task: TaskOpt = None,
        checkpoint: CheckpointOpt = None, seed: SeedOpt = 0, threads: ThreadsOpt = None, spec: SpecOption = None,
        variant: VariantOption = None, motor_params: MotorParamsOption = None,
        asymmetric: AsymmetricOption = False, on_fall: OnFallOption = "stop", terrain: TerrainOption = None,
        terrain_seed: TerrainSeedOption = 0, step_in_place: StepInPlaceOption = False) -> None:
    """Run a policy on the simulated robot and print a summary (distance, tracking errors, falls)."""
    from toddlerbot.sessions.sim import sim_session

    robot_options = RobotOptions.of(spec, variant, motor_params)
    _check_options(policy, seconds, control_hz, {"motion": motion, "weights": weights, "checkpoint": checkpoint,
                   "threads": threads}, {"--log": log, "--video": video, "--snapshot": snapshot,
                                         "--summary-json": summary_json},
                   [command_file, motion, weights, checkpoint, *robot_options.files])
    schedule, ground = _schedule(command, command_file), terrain and parse_terrain(terrain)
    description, base = robot_options.load()
    if base != "floating":  # the simulator's robot stands on the floor; a fixed base is for `model build`
        raise ToddlerbotError(f"sim run simulates the floating robot; --variant selects a {base} base "
                              "(use a floating variant: floating, gripper)")
    _check_control_rate(control_hz, description.spec.simulation.timestep)
    session = sim_session(policy, schedule, seconds, description, control_hz, realtime, task, seed,
                          camera if video or snapshot else None, viewer, on_fall, ground, terrain_seed, motion=motion,
                          weights=weights, checkpoint=checkpoint, threads=threads,
                          **symmetric_option(policy, asymmetric), **stand_option(policy, step_in_place))
    with RunProgress(f"simulating {policy}", round(seconds / session.robot.control_dt)) as progress:
        result = session.run(progress, log_path=log)
    for path in session.write_video(video, snapshot):
        console.print(f"wrote {path}")
    wanted = [f"{kind} {path}" for kind, path in (("video", video), ("snapshot", snapshot)) if path]
    skipped = session.render_skipped and f"{' and '.join(wanted)} skipped: {session.render_skipped}"
    _report(policy, result, session.policy, session.scene, log, summary_json, skipped)


def _check_options(policy: str, seconds: float, control_hz: float, policy_options: dict, outputs: dict,
                   inputs: list) -> None:
    from toddlerbot.policies import check_policy_options

    check_run_policy(policy)
    check_policy_options(policy, **policy_options)
    duration(seconds, "--seconds")
    positive(control_hz, "--control-hz", "Hz")
    for option, path in outputs.items():
        if path is not None:
            output_file(path, option, inputs)


def _schedule(command: str | None, command_file: Path | None):
    """The schedule asked for, or None for the policy's own `demo_command` (parsed before any work starts)."""
    from toddlerbot.runtime.commands import CommandSchedule

    if command_file:
        return CommandSchedule.from_file(command_file)
    return None if command is None else CommandSchedule.parse(command)


def _report(policy: str, result, pol, scene, log: Path | None, summary_json: Path | None,
            render_skipped: str | None) -> None:
    """Save the log and summary asked for, print the summary; a fall exits 1."""
    from toddlerbot.runtime.summary import summarize

    summary = summarize(result.log, result.fell, result.fall_time, falls=result.falls, recoveries=result.recoveries)
    if log:
        result.log.save(log)
        console.print(f"wrote {log}")
    if summary_json:
        extra = (({} if scene is None else {"task": scene.to_dict()})
                 | ({} if pol.status is None else {pol.name: pol.status.to_dict()}))
        atomic_write_text(summary_json, json_text(summary.to_dict() | extra, indent=2))
    status = f"[red]FELL[/] at {summary.fall_time_s:.2f} s" if summary.fell else "[green]no fall[/]"
    if summary.recoveries:
        status = f"{summary.falls} falls, got up from {summary.recoveries}" + ("; " + status if summary.fell else "")
    console.print(f"[bold]{policy}[/] {summary.duration_s:.2f} s: {status}; {summary.motion_text()}; compute "
                  f"{summary.mean_compute_ms:.2f} ms/step")
    for part in (scene, pol.status):
        if part is not None:
            console.print(part.describe(), highlight=False)
    if render_skipped:
        console.print(render_skipped, highlight=False, markup=False, soft_wrap=True)
    if summary.fell:
        raise typer.Exit(1)


def _check_control_rate(control_hz: float, timestep: float) -> None:
    """The simulator takes whole physics steps (`timestep`, s) per control step: refuse other rates in one line."""
    substeps = round(1.0 / (control_hz * timestep))
    if substeps < 1 or abs(substeps * timestep - 1.0 / control_hz) > 1e-9:
        raise ToddlerbotError(f"--control-hz {control_hz:g}: expected the {1 / timestep:g} Hz physics rate divided "
                              "by a whole number, e.g. 50")


@app.command()
def plot(
    log: Annotated[Path, typer.Argument(help="Run log (.npz) from `sim run --log`.")],
    out: Annotated[Path, typer.Option("-o", "--out", help="Directory for the PNGs.")] = Path("plots"),
) -> None:
    """Plot a run log: per-joint tracking, IMU signals, loop-time histogram."""
    from toddlerbot.runtime.log import RunLog
    from toddlerbot.runtime.plot import plot_log

    output_dir(out, "--out")
    for path in plot_log(RunLog.load(log), out):
        console.print(f"wrote {path}")
