"""Setting up and running teleoperation (`toddlerbot teleop`): the simulated robot of a teleop task, the input
source, the leader link, the walking policy, and the run itself (`runtime.run_policy` with a `WallClock`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Robot
from toddlerbot.runtime.runner import RunObserver, WallClock, run_policy
from toddlerbot.tasks import task_description
from toddlerbot.teleop.follower import ArmFollower
from toddlerbot.teleop.link import LinkSubscriber
from toddlerbot.teleop.session import CommandSource

MAX_TELEOP_SECONDS = 12 * 3600.0
"""Longest teleoperation session, s (a day of data collection); also the limit of one run until Esc."""


@dataclass(frozen=True)
class TeleopRobot:
    robot: Robot
    head_image: Callable[[], np.ndarray] | None
    """The head camera's policy image (sim), None where there is none."""
    walks: bool
    """False where the torso is mounted (the pick task's table): no walking policy then."""


WALK = "walk"
"""The teleop task without a scene: the robot on the floor. Every other is a registered task's scene."""


def teleop_tasks() -> tuple[str, ...]:
    """What `teleop --task` takes: the floor, then every registered task."""
    from toddlerbot.tasks import TASKS

    return (WALK, *TASKS.names())


def sim_robot(task: str, seed: int, description: RobotDescription | None = None) -> TeleopRobot:
    """The simulated robot of a teleop task (gripper variant): the floor, or the registered task's teleop robot in
    its scene (`Task.teleop_robot`; a mounted task's torso stays at its table: no walking)."""
    description = task_description(description)
    if task == WALK:
        from toddlerbot.sim.mujoco_robot import MuJoCoRobot
        from toddlerbot.tasks.camera import HeadCamera

        robot = MuJoCoRobot(description)
        camera = HeadCamera(robot.model, robot.data, description.handles.head_camera or "head_camera")
        return TeleopRobot(robot, camera.image, walks=True)
    from toddlerbot.tasks import make_task

    the_task = make_task(task, description)
    return TeleopRobot(the_task.teleop_robot(seed), the_task.head_image, walks=not the_task.mounted)


def walking_policy(name: str, robot: Robot) -> Policy:
    """The registered policy `name`, which must follow velocity commands (a command reach): the controller steers
    it."""
    from toddlerbot.policies import make_policy

    policy = make_policy(name, robot)
    if policy.command_reach is None:
        raise ToddlerbotError(f"--policy {name}: it follows no velocity command; teleop steers a walking policy "
                              "(one with a command reach, e.g. walk-zmp)")
    return policy


def input_source(kind: str, mapping: Path | None, log: Callable[[str], None]) -> CommandSource:
    """``keyboard``; ``joystick`` (a controller, or an error); ``leader`` (walking from a controller if one is
    connected, else the keyboard)."""
    from toddlerbot.teleop.gamepad import load_mapping
    from toddlerbot.teleop.sdl_input import InputError, JoystickInput, KeyboardInput

    pad = load_mapping(mapping)
    if kind == "keyboard":
        return KeyboardInput(pad)
    try:
        source = JoystickInput(pad)
        log(f"controller: {source.name}")
        return source
    except InputError:
        if kind == "joystick":
            raise
        log("no controller: walking and neck from the keyboard")
        return KeyboardInput(pad)


def leader_link(endpoint: str | None, robot: Robot) -> tuple[LinkSubscriber, ArmFollower]:
    """The leader arms' link (default: the local endpoint) and the follower of the robot's recorded motors."""
    from toddlerbot.tasks.space import ManipulationSpace
    from toddlerbot.teleop.link import DEFAULT_ENDPOINT

    space = ManipulationSpace.of(robot.description)
    return LinkSubscriber(endpoint or DEFAULT_ENDPOINT), ArmFollower(robot.motor_names, space.names)


def run_teleop(robot: Robot, policy: Policy, seconds: float, observers: Sequence[RunObserver] = (),
               viewer: bool = False, log: Callable[[str], None] = print) -> None:
    """Run `policy` (a teleop session, perhaps with chains) in real time for `seconds` (0: until Esc or Ctrl-C),
    with the MuJoCo viewer if asked; the robot is closed however it ends. Teleoperation goes on after a fall (the
    operator decides)."""
    shown = None
    if viewer:
        from toddlerbot.runtime.observers import ViewerObserver

        shown = ViewerObserver(robot)  # type: ignore[arg-type]
    log("teleoperating: Menu (or Return) marks episodes, Esc or Ctrl-C stops")
    try:
        run_policy(robot, policy, seconds=seconds or MAX_TELEOP_SECONDS, clock=WallClock(),
                   observers=[*observers, shown] if shown is not None else observers, stop_on_fall=False,
                   record_log=False)  # the recorded episodes are the session's record
    except KeyboardInterrupt:
        log("stopped")
    finally:
        if shown is not None:
            shown.close()
        robot.close()
