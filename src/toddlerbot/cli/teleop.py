"""`toddlerbot teleop ...`: drive the robot (sim or real) from a game controller, the keyboard or leader arms."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import ImuOption, duration, open_robot_imu, output_dir, within
from toddlerbot.cli.output import console
from toddlerbot.errors import ToddlerbotError
from toddlerbot.tasks.scenes import SCENES

app = typer.Typer(help="Teleoperation: game controller (Table 4), keyboard, leader-follower arms; record episodes.",
                  invoke_without_command=True)

BACKENDS = ("sim", "real")
INPUTS = ("joystick", "keyboard", "leader")
SIM_TASKS = ("walk", *SCENES)
MAX_TELEOP_SECONDS = 12 * 3600.0
"""Longest timed teleoperation session, s (a day of data collection; 0 runs until Esc)."""


@app.callback()
def teleop(
    ctx: typer.Context,
    backend: Annotated[str, typer.Option("--backend", help="sim (MuJoCo) or real (Dynamixel bus).")] = "sim",
    input_kind: Annotated[str, typer.Option("--input", help="joystick, keyboard, or leader (arms from the leader "
                                            "link; walking from a controller if one is connected, else keys).")]
        = "joystick",
    task: Annotated[str, typer.Option("--task", help="Sim scene: walk (floor), pick (table and cube, torso "
                                      "mounted), wagon.")] = "walk",
    out: Annotated[Path | None, typer.Option("-o", "--out", help="Record episodes (Menu marks start and end) into "
                                             "this dataset directory.")] = None,
    policy: Annotated[str, typer.Option("--policy", help="Walking policy: walk-zmp or walk-rl.")] = "walk-zmp",
    mapping: Annotated[Path | None, typer.Option("--mapping", help="Controller mapping YAML (default: Table 4).")]
        = None,
    seconds: Annotated[float, typer.Option("--seconds", help="Stop after this long (0: run until Esc/Ctrl-C).")]
        = 0.0,
    link: Annotated[str | None, typer.Option("--link", help="Leader link endpoint (ZeroMQ; default: the local "
                                             "one, manipulation.link.DEFAULT_ENDPOINT).")] = None,
    port: Annotated[str | None, typer.Option("--port", help="Serial port of the robot (real backend).")] = None,
    calibration: Annotated[Path | None, typer.Option("--calibration", help="Robot calibration YAML (real).")]
        = None,
    imu: ImuOption = "bno08x",
    seed: Annotated[int, typer.Option("--seed", help="Scene seed (pick).")] = 0,
    viewer: Annotated[bool, typer.Option("--viewer", help="Show the MuJoCo viewer (sim; needs a display).")] = False,
    chains: Annotated[list[str] | None, typer.Option("--chain", help="Skill chain (shipped name or file) run while "
                                                     "its button is held; default (sim): the shipped chains of "
                                                     "the task's scene, e.g. wagon on L2, pick on L1.")] = None,
) -> None:
    """Teleoperate: left stick walks, right stick turns, D-pad moves the waist, Y/A/X/B the neck, Menu marks
    episodes; with --input leader the arms follow the leader arms. Runs at 50 Hz in real time."""
    if ctx.invoked_subcommand is not None:
        return
    from toddlerbot.tasks.space import ManipulationSpace
    from toddlerbot.teleop.gamepad import load_mapping
    from toddlerbot.teleop.session import EpisodeRecorder, TeleopSession

    for name, value, allowed in (("--backend", backend, BACKENDS), ("--input", input_kind, INPUTS),
                                 ("--task", task, SIM_TASKS), ("--policy", policy, ("walk-zmp", "walk-rl"))):
        if value not in allowed:
            raise ToddlerbotError(f"{name} {value!r}: expected one of {', '.join(allowed)}")
    if out is not None and out.is_dir() and any(out.iterdir()):
        raise ToddlerbotError(f"{out} exists and is not empty")
    if out is not None:
        output_dir(out, "--out")
    if seconds:  # 0: until Esc or Ctrl-C
        duration(seconds, "--seconds", MAX_TELEOP_SECONDS)
    pad = load_mapping(mapping)
    robot, camera, walks = _robot(backend, task, port, calibration, seed, imu)
    source = _source(input_kind, pad)
    leader = _leader_link(link, robot) if input_kind == "leader" else None
    walker = None
    if walks:
        from toddlerbot.policies import make_policy

        walker = make_policy(policy, robot)
    recorder = None
    if out is not None:
        recorder = EpisodeRecorder(f"teleop {task}", ManipulationSpace.of(robot.description), camera)
    hook = _chain_hook(chains, backend, task, robot, camera)
    session = TeleopSession(robot, source, walker, recorder, leader, skill_hook=hook, log=console.print)
    _run(session, robot, source, seconds, viewer and backend == "sim")
    if recorder is not None:
        _write(out, recorder)


def _robot(backend: str, task: str, port: str | None, calibration: Path | None, seed: int, imu: str):
    from toddlerbot.robot.description import RobotDescription

    description = RobotDescription.load(variant="gripper")
    if backend == "real":
        if port is None or calibration is None:
            raise ToddlerbotError("--backend real needs --port and --calibration")
        from toddlerbot.hardware.calibration import load_calibration
        from toddlerbot.hardware.real_robot import RealRobot

        robot = RealRobot(description, port, load_calibration(calibration, description),
                          imu=open_robot_imu(imu, port, "teleop (it walks)"))
        return robot, None, True
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot
    from toddlerbot.tasks.camera import HeadCamera

    if task == "pick":
        from toddlerbot.tasks.pick import PickTask, TaskRobot

        pick = PickTask(description)
        pick.reset(seed)
        return TaskRobot(pick, seed), pick.head_image, False
    model = None
    if task == "wagon":
        from toddlerbot.tasks.scenes import scene_model

        model = scene_model(description, "wagon")
    robot = MuJoCoRobot(description, model=model)
    camera = HeadCamera(robot.model, robot.data, description.handles.head_camera or "head_camera")
    return robot, camera.image, True


def _chain_hook(names: list[str] | None, backend: str, task: str, robot, camera=None):
    """The skill hook running the chains `names` (default in sim: the shipped chains of the task's scene) on their
    buttons; `camera` gives a `dp` skill its head-camera images."""
    from toddlerbot.skills.spec import SHIPPED_DIR, load_chain

    groups = tuple(robot.description.groups)
    if names is None:
        shipped = [load_chain(p, groups) for p in sorted(SHIPPED_DIR.glob("*.yaml"))] if backend == "sim" else []
        chains = [c for c in shipped if c.scene == task and c.button is not None]
    else:
        chains = [load_chain(name, groups) for name in names]
    if not chains:
        return None
    from toddlerbot.skills.teleop_hook import ChainHook

    if backend == "real":
        from toddlerbot.tasks.scenes import scene_model

        hook = ChainHook(chains, robot, scene_model(robot.description, chains[0].scene), head_image=camera,
                         log=console.print)
    else:
        from toddlerbot.tasks.probe import SceneProbe

        hook = ChainHook(chains, robot, robot.model, SceneProbe(robot.model, robot.data), head_image=camera,
                         log=console.print)
    for button, chain in hook.bound.items():
        console.print(f"hold {button.upper()} to run chain {chain.name}")
    return hook


def _source(input_kind: str, pad):
    from toddlerbot.teleop.sdl_input import InputError, JoystickInput, KeyboardInput

    if input_kind == "keyboard":
        return KeyboardInput(pad)
    try:
        source = JoystickInput(pad)
        console.print(f"controller: {source.name}")
        return source
    except InputError:
        if input_kind == "joystick":
            raise
        console.print("no controller: walking and neck from the keyboard")
        return KeyboardInput(pad)


def _leader_link(endpoint: str | None, robot):
    from toddlerbot.tasks.space import ManipulationSpace
    from toddlerbot.teleop.follower import ArmFollower
    from toddlerbot.teleop.link import DEFAULT_ENDPOINT, LinkSubscriber

    space = ManipulationSpace.of(robot.description)
    return LinkSubscriber(endpoint or DEFAULT_ENDPOINT), ArmFollower(robot.motor_names, space.names)


def _run(session, robot, source, seconds: float, viewer: bool) -> None:
    handle = None
    if viewer:
        import mujoco.viewer

        from toddlerbot.sim.render import show_visuals

        handle = mujoco.viewer.launch_passive(robot.model, robot.data)
        show_visuals(handle.opt)  # the robot as it looks; the viewer's group toggles (2, 3) switch to collision
    session.reset()
    dt = robot.control_dt
    start = next_tick = time.monotonic()
    console.print("teleoperating: Menu (or Return) marks episodes, Esc or Ctrl-C stops")
    try:
        while not seconds or time.monotonic() - start < seconds:
            session.step()
            if handle is not None:
                handle.sync()
            if getattr(source, "quit_requested", False):
                break
            next_tick += dt
            time.sleep(max(0.0, next_tick - time.monotonic()))
    except KeyboardInterrupt:
        console.print("stopped")
    finally:
        if handle is not None:
            handle.close()
        robot.close()


def _write(out: Path, recorder) -> None:
    from toddlerbot.datasets.episode import resample
    from toddlerbot.datasets.lerobot_writer import write_dataset
    from toddlerbot.tasks.record import DATASET_FPS

    if recorder.active:
        console.print(recorder.toggle())
    if not recorder.episodes:
        console.print("no episode recorded (press Menu to start and end one)")
        return
    write_dataset(out, [resample(e, DATASET_FPS) for e in recorder.episodes], recorder.space.names, DATASET_FPS,
                  raw_episodes=recorder.episodes)
    console.print(f"wrote {out}: {len(recorder.episodes)} episode(s)")


@app.command()
def leader(
    port: Annotated[str, typer.Option("--port", help="Serial port of the leader arms' bus.")],
    calibration: Annotated[Path, typer.Option("--calibration", help="Leader calibration YAML (zero offsets).")],
    link: Annotated[str | None, typer.Option("--link", help="Endpoint to publish on (bind; default: the local "
                                             "one, manipulation.link.DEFAULT_ENDPOINT).")] = None,
    rate: Annotated[float, typer.Option("--rate", help="Read/publish rate, Hz.")] = 50.0,
) -> None:
    """Leader side: read the leader arms (torque off) and publish their angles until Ctrl-C."""
    import threading

    from toddlerbot.hardware.calibration import load_calibration
    from toddlerbot.hardware.leader import LeaderArms
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.teleop.leader_follower import stream_leader
    from toddlerbot.teleop.link import DEFAULT_ENDPOINT, LinkPublisher

    link = link or DEFAULT_ENDPOINT
    within(rate, "--rate", 0.1, 1000.0, "Hz")
    description = RobotDescription.load(variant="gripper")
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
        time.sleep(0.02)
