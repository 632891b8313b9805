"""`toddlerbot sim ...`: run a policy on the simulated robot, render it, summarise and plot run logs."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import check_run_policy, duration, output_dir, output_file, positive, run_policy_names
from toddlerbot.cli.output import console
from toddlerbot.cli.sim_compare import compare_command
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_text, json_text
from toddlerbot.robot.interface import CONTROL_DT

app = typer.Typer(help="Simulate ToddlerBot in MuJoCo: walk, stand, replay motions; render and plot runs.",
                  no_args_is_help=True)
app.command("compare")(compare_command)


@app.command()
def run(
    policy: Annotated[str, typer.Option("--policy", help=f"One of: {', '.join(run_policy_names())}.")] = "walk-zmp",
    command: Annotated[str | None, typer.Option(
        "--command", help="Velocity schedule 'time: vx,vy,yaw_rate; ...' (s: m/s, m/s, rad/s), e.g. "
        "'0:0.1,0,0; 5:0,0,0.3'. Default: 0.1 m/s forward for walk-zmp, zero otherwise.")] = None,
    command_file: Annotated[
        Path | None, typer.Option("--command-file", help="Schedule file (one entry per line); overrides --command.")
    ] = None,
    motion: Annotated[str | None, typer.Option("--motion", help="For --policy replay: squat, wave, look_around "
                                               "or a motion YAML file.")] = None,
    weights: Annotated[Path | None, typer.Option("--weights", help="For --policy walk-rl: an exported policy (.npz, "
                                                 "or .onnx run by onnxruntime), or a shipped one by name: walk_rl "
                                                 "(default, CPU-trained) or walk_rl_gpu.")] = None,
    seconds: Annotated[float, typer.Option("--seconds", help="Duration, s (replay stops at the motion's end).")] = 10.0,
    control_hz: Annotated[float, typer.Option("--control-hz", help="Control rate, Hz.")] = 1.0 / CONTROL_DT,
    realtime: Annotated[bool, typer.Option("--realtime", help="Lock the loop to wall-clock time.")] = False,
    video: Annotated[Path | None, typer.Option("--video", help="Write an MP4 from the tracking camera.")] = None,
    snapshot: Annotated[Path | None, typer.Option("--snapshot", help="Write a PNG of the last frame.")] = None,
    camera: Annotated[str, typer.Option("--camera", help="perspective, side, front, top or head_camera.")] =
        "perspective",
    viewer: Annotated[bool, typer.Option("--viewer", help="Open the interactive MuJoCo viewer (needs a display; "
                                         "implies --realtime).")] = False,
    log: Annotated[Path | None, typer.Option("--log", help="Save the run log (.npz).")] = None,
    summary_json: Annotated[Path | None, typer.Option("--summary-json", help="Write the summary as JSON.")] = None,
    motor_params: Annotated[list[Path] | None, typer.Option(
        "--motor-params", help="params.json from `toddlerbot sysid fit` (repeatable): simulate fitted motors.")] = None,
    task: Annotated[str | None, typer.Option("--task", help="For --policy dp: the manipulation scene (pick; the "
                                             "gripper variant, the head camera as the policy's camera).")] = None,
    checkpoint: Annotated[Path | None, typer.Option("--checkpoint", help="For --policy dp: a checkpoint from "
                                                    "`dp train`/`dp export` (default: the one shipped for --task).")]
        = None,
    seed: Annotated[int, typer.Option("--seed", help="For --task: scene seed (the cube's pose).")] = 0,
    threads: Annotated[int, typer.Option("--threads", min=1, help="For --policy dp: CPU threads for torch.")] = 1,
) -> None:
    """Run a policy on the simulated robot and print a summary (distance, tracking errors, falls)."""
    from rich.progress import Progress

    from toddlerbot.policies import make_policy
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.runtime.commands import CommandSchedule
    from toddlerbot.runtime.runner import run_policy
    from toddlerbot.runtime.summary import summarize
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig
    from toddlerbot.sim.render import Recorder, RenderError, has_display, show_visuals

    check_run_policy(policy)
    if (task is not None or checkpoint is not None) and policy != "dp":
        raise ToddlerbotError("--task and --checkpoint are for --policy dp")
    if weights is not None and policy != "walk-rl":
        raise ToddlerbotError("--weights is for --policy walk-rl")
    duration(seconds, "--seconds")
    positive(control_hz, "--control-hz", "Hz")
    outputs = {"--log": log, "--video": video, "--snapshot": snapshot, "--summary-json": summary_json}
    for option, path in outputs.items():
        if path is not None:
            output_file(path, option)
    if command is None:
        command = "0:0.1,0,0" if policy == "walk-zmp" else "0:0,0,0"
    schedule = CommandSchedule.from_file(command_file) if command_file else CommandSchedule.parse(command)
    description = RobotDescription.load(motor_params=motor_params or [])
    _check_control_rate(control_hz, description.spec.simulation.timestep)
    scene = None
    if policy == "dp":
        from toddlerbot.cli.dp_live import sim_dp_policy

        robot, pol, scene = sim_dp_policy(description, task or "pick", checkpoint, seed, realtime or viewer,
                                          1.0 / control_hz, threads)
    else:
        robot = MuJoCoRobot(description, SimConfig(control_dt=1.0 / control_hz))
        pol = make_policy(policy, robot, motion, weights)
    recorder, render_skipped = None, None
    if video or snapshot:
        try:
            recorder = Recorder(robot.model, robot.data, camera)
        except RenderError as exc:  # simulate anyway; say after the summary what was skipped and why
            wanted = [f"{kind} {path}" for kind, path in (("video", video), ("snapshot", snapshot)) if path]
            render_skipped = f"{' and '.join(wanted)} skipped: {exc}"
    frame_every = max(1, round(1.0 / 30.0 / robot.control_dt))
    handle = None
    if viewer:
        if not has_display():
            raise ToddlerbotError("--viewer needs a display (DISPLAY or WAYLAND_DISPLAY); use --video instead")
        import mujoco.viewer

        handle = mujoco.viewer.launch_passive(robot.model, robot.data)
        show_visuals(handle.opt)  # the robot as it looks; the viewer's group toggles (2, 3) switch to collision
        realtime = True
    steps = {"n": 0}

    with Progress(console=console, transient=True) as progress:
        task = progress.add_task(f"simulating {policy}", total=round(seconds / robot.control_dt))

        def on_step(obs) -> None:
            if scene is not None:
                scene.observe()
            if recorder is not None and steps["n"] % frame_every == 0:
                recorder.capture()
            if handle is not None:
                handle.sync()
            steps["n"] += 1
            progress.advance(task)

        try:
            result = run_policy(robot, pol, schedule, seconds, realtime=realtime, on_step=on_step)
        finally:
            if scene is not None:
                pol.close()
    if handle is not None:
        handle.close()
    summary = summarize(result.log, result.fell, result.fall_time)
    extra = {} if scene is None else {"dp": pol.status.to_dict(), "task": scene.to_dict()}
    if recorder is not None:
        if video:
            recorder.write_video(video, fps=1.0 / (frame_every * robot.control_dt))
            console.print(f"wrote {video} ({len(recorder.frames)} frames)")
        if snapshot:
            recorder.write_png(snapshot)
            console.print(f"wrote {snapshot}")
        recorder.close()
    if log:
        result.log.save(log)
        console.print(f"wrote {log}")
    if summary_json:
        atomic_write_text(summary_json, json_text(summary.to_dict() | extra, indent=2))
    t = summary.tracking
    status = f"[red]FELL[/] at {summary.fall_time_s:.2f} s" if summary.fell else "[green]no fall[/]"
    console.print(
        f"[bold]{policy}[/] {summary.duration_s:.2f} s: {status}; displacement "
        f"({summary.displacement_m[0]:+.3f}, {summary.displacement_m[1]:+.3f}) m, path {summary.distance_m:.3f} m, "
        f"yaw change {summary.yaw_change_rad:+.3f} rad\n"
        f"tracking errors: position {t.position_m:.3f} m, linear velocity {t.lin_vel_mps:.3f} m/s, "
        f"angular velocity {t.ang_vel_radps:.3f} rad/s; compute {summary.mean_compute_ms:.2f} ms/step"
    )
    if scene is not None:
        from toddlerbot.cli.dp_live import describe_status

        console.print(f"{scene.describe()}\n{describe_status(pol.status)}", highlight=False)
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
