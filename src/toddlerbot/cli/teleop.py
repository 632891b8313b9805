"""`toddlerbot teleop ...`: drive the robot (sim or real) from a game controller, the keyboard or leader arms."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Literal

import typer

from toddlerbot.cli.options import (
    ImuOption,
    MotorParamsOption,
    RobotOptions,
    SpecOption,
    VariantOption,
    duration,
    seed_option,
    within,
)
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir
from toddlerbot.robot.interface import CONTROL_DT, CONTROL_HZ
from toddlerbot.tasks import GRIPPER
from toddlerbot.teleop.launch import MAX_TELEOP_SECONDS, teleop_tasks

app = typer.Typer(help="Teleoperation: game controller (Table 4), keyboard, leader-follower arms; record episodes.",
                  invoke_without_command=True)

BackendOption = Annotated[Literal["sim", "real"], typer.Option("--backend", help="sim (MuJoCo) or real (Dynamixel "
                                                                                 "bus).")]
InputOption = Annotated[Literal["joystick", "keyboard", "leader"], typer.Option(
    "--input", help="joystick, keyboard, or leader (arms from the leader link; walking from a controller if one is "
                    "connected, else keys).")]


def _teleop_task(name: str) -> str:
    """`name` if teleop knows it (registered tasks are found at run time, so no fixed choice list)."""
    if name not in teleop_tasks():
        raise typer.BadParameter(f"{name!r} is not one of {', '.join(teleop_tasks())}", param_hint="--task")
    return name


TaskOption = Annotated[str, typer.Option(
    "--task", callback=_teleop_task, help="Sim scene: walk (the floor) or a registered task's (pick: table and cube, "
                                          "torso mounted; wagon).")]
OutOption = Annotated[Path | None, typer.Option("-o", "--out", help="Record episodes (Menu marks start and end) into "
                                                                    "this dataset directory.")]
PolicyOption = Annotated[str, typer.Option("--policy", help="Walking policy (a registered one that follows velocity "
                                                            "commands: walk-zmp, walk-rl).")]
MappingOption = Annotated[Path | None, typer.Option("--mapping", help="Controller mapping YAML (default: Table 4).")]
SecondsOption = Annotated[float, typer.Option("--seconds", help="Stop after this long (0: run until Esc/Ctrl-C).")]
LinkOption = Annotated[str | None, typer.Option("--link", help="Leader link endpoint (ZeroMQ; default: the local "
                                                               "one, manipulation.link.DEFAULT_ENDPOINT).")]
PortOption = Annotated[str | None, typer.Option("--port", help="Serial port of the robot (real backend).")]
CalibrationOption = Annotated[Path | None, typer.Option("--calibration", help="Robot calibration YAML (real).")]
SeedOption = Annotated[int, seed_option(help="Scene seed (pick).")]
ViewerOption = Annotated[bool, typer.Option("--viewer", help="Show the MuJoCo viewer (sim; needs a display).")]
ChainsOption = Annotated[list[str] | None, typer.Option(
    "--chain", help="Skill chain (shipped name or file) run while its button is held; default (sim): the shipped "
                    "chains of the task's scene, e.g. wagon on L2, pick on L1.")]


@app.callback()
def teleop(ctx: typer.Context, backend: BackendOption = "sim", input_kind: InputOption = "joystick",
           task: TaskOption = "walk", out: OutOption = None, policy: PolicyOption = "walk-zmp",
           mapping: MappingOption = None, seconds: SecondsOption = 0.0, link: LinkOption = None,
           port: PortOption = None, calibration: CalibrationOption = None, imu: ImuOption = "bno08x",
           seed: SeedOption = 0, viewer: ViewerOption = False, chains: ChainsOption = None, spec: SpecOption = None,
           variant: VariantOption = GRIPPER, motor_params: MotorParamsOption = None) -> None:
    """Teleoperate: left stick walks, right stick turns, D-pad moves the waist, Y/A/X/B the neck, Menu marks
    episodes; with --input leader the arms follow the leader arms. Runs at 50 Hz in real time."""
    if ctx.invoked_subcommand is not None:
        return
    from toddlerbot.sessions.teleop import teleop_session

    _check_outputs(out, seconds, [mapping, calibration])
    run = teleop_session(RobotOptions.of(spec, variant, motor_params).description(), backend, input_kind, task,
                         policy, mapping, link, port, calibration, imu, seed, chains, record=out is not None,
                         log=console.print)
    run.run(seconds, viewer, console.print)
    if out is not None:
        run.write(out, console.print)


def _check_outputs(out: Path | None, seconds: float, inputs: list) -> None:
    if out is not None:
        output_dir(out, "--out", inputs, empty="; record into a new folder")
    if seconds:  # 0: until Esc or Ctrl-C
        duration(seconds, "--seconds", MAX_TELEOP_SECONDS)


@app.command()
def leader(
    port: Annotated[str, typer.Option("--port", help="Serial port of the leader arms' bus.")],
    calibration: Annotated[Path, typer.Option("--calibration", help="Leader calibration YAML (zero offsets).")],
    link: Annotated[str | None, typer.Option("--link", help="Endpoint to publish on (bind; default: the local "
                                             "one, manipulation.link.DEFAULT_ENDPOINT).")] = None,
    rate: Annotated[float, typer.Option("--rate", help="Read/publish rate, Hz.")] = CONTROL_HZ,
    spec: SpecOption = None,
    variant: VariantOption = GRIPPER,
) -> None:
    """Leader side: read the leader arms (torque off) and publish their angles until Ctrl-C."""
    import threading

    from toddlerbot.hardware.calibration import load_calibration
    from toddlerbot.hardware.leader import LeaderArms
    from toddlerbot.teleop.leader_follower import stream_leader
    from toddlerbot.teleop.link import DEFAULT_ENDPOINT, LinkPublisher

    link = link or DEFAULT_ENDPOINT
    within(rate, "--rate", 0.1, 1000.0, "Hz")
    description = RobotOptions.of(spec, variant).description()
    offsets = load_calibration(calibration, description).offsets
    stop = threading.Event()
    with LeaderArms(description, port, offsets) as arms:
        publisher = LinkPublisher(link)
        console.print(f"leader: publishing {len(arms.names)} joints on {link} at {rate:g} Hz; Ctrl-C stops")
        started = time.monotonic()
        try:
            sent = stream_leader(arms, publisher, stop, rate, on_error=lambda e: console.print(f"leader: {e}"))
        except KeyboardInterrupt:
            stop.set()
            sent = publisher.seq
        finally:
            publisher.close()
    console.print(f"sent {sent} messages in {time.monotonic() - started:.1f} s")


@app.command()
def probe(
    seconds: Annotated[float, typer.Option("--seconds", help="How long to listen.")] = 10.0,
) -> None:
    """Print which controller axis, button or hat moves (to edit the mapping file)."""
    from toddlerbot.teleop.gamepad import load_mapping
    from toddlerbot.teleop.sdl_input import JoystickInput

    duration(seconds, "--seconds")
    source = JoystickInput(load_mapping())
    console.print(f"{source.name}: move sticks and press buttons ({seconds:g} s)")
    last = source.state()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        state = source.state()
        for i, (a, b) in enumerate(zip(last.axes, state.axes)):
            if abs(a - b) > 0.3:
                console.print(f"axis {i}: {b:+.2f}")
        for i, (a, b) in enumerate(zip(last.buttons, state.buttons)):
            if a != b:
                console.print(f"button {i}: {'down' if b else 'up'}")
        for i, (a, b) in enumerate(zip(last.hats, state.hats)):
            if a != b:
                console.print(f"hat {i}: {b}")
        last = state
        time.sleep(CONTROL_DT)
