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


def _floor(description: RobotDescription, seed: int, scene: str | None = None) -> TeleopRobot:
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot
    from toddlerbot.tasks.camera import HeadCamera
    from toddlerbot.tasks.scenes import scene_model

    robot = MuJoCoRobot(description, model=None if scene is None else scene_model(description, scene))
    camera = HeadCamera(robot.model, robot.data, description.handles.head_camera or "head_camera")
    return TeleopRobot(robot, camera.image, walks=True)


def _pick(description: RobotDescription, seed: int) -> TeleopRobot:
    from toddlerbot.tasks.pick import PickTask, TaskRobot

    task = PickTask(description)
    return TeleopRobot(TaskRobot(task, seed), task.head_image, walks=False)  # reset: the cube placed for the seed


def _wagon(description: RobotDescription, seed: int) -> TeleopRobot:
    return _floor(description, seed, "wagon")


SIM_TASKS: dict[str, Callable[[RobotDescription, int], TeleopRobot]] = {"walk": _floor, "pick": _pick,
                                                                        "wagon": _wagon}
"""--task -> its simulated robot: the floor, the pick task (torso mounted at the table), the wagon scene."""


def sim_robot(task: str, seed: int, description: RobotDescription | None = None) -> TeleopRobot:
    """The simulated robot of a teleop task (gripper variant)."""
    return SIM_TASKS[task](description or RobotDescription.load(variant="gripper"), seed)


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
