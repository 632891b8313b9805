"""Teleoperation input: the Table 4 mapping, an SDL virtual game controller, the keyboard fallback, and a teleop
session that walks the simulated robot and records an episode."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
pygame = pytest.importorskip("pygame")

from sdl_support import VirtualJoystick  # noqa: E402
from toddlerbot.teleop.gamepad import (  # noqa: E402
    GamepadMapper,
    GamepadState,
    MappingError,
    apply_dead_zone,
    load_mapping,
)
from toddlerbot.teleop.sdl_input import JoystickInput, KeyboardInput  # noqa: E402

MAPPING = load_mapping()


@pytest.fixture(scope="module")
def _virtual_joystick():
    from toddlerbot.teleop.sdl_input import open_sdl

    stick = VirtualJoystick(open_sdl())
    yield stick
    stick.detach()


@pytest.fixture
def joystick(_virtual_joystick):
    """The module's virtual controller, all sticks centred, buttons and D-pad released."""
    stick = _virtual_joystick
    for axis in (0, 1, 3, 4):
        stick.axis(axis, 0.0)
    for axis in (2, 5):
        stick.axis(axis, -1.0)
    for button in range(15):
        stick.button(button, False)
    stick.hat(0, 0, 0)
    return stick


def test_dead_zone_rescales_to_full_deflection():
    assert apply_dead_zone(0.1, 0.12) == 0.0
    assert apply_dead_zone(1.0, 0.12) == pytest.approx(1.0)
    assert apply_dead_zone(-0.56, 0.12) == pytest.approx(-0.5)


def test_mapping_errors_name_the_file_and_field(tmp_path):
    bad = tmp_path / "pad.yaml"
    text = (MAPPING.model_dump_json())
    import json

    raw = json.loads(text)
    raw["axes"]["walk_x"]["axis"] = -1
    import yaml

    bad.write_text(yaml.safe_dump(raw))
    with pytest.raises(MappingError, match=r"pad\.yaml: axes\.walk_x\.axis: Input should be greater than or equal"):
        load_mapping(bad)
    raw["axes"]["walk_x"]["axis"] = 1
    raw["keyboard"]["z"] = "fly"
    bad.write_text(yaml.safe_dump(raw))
    with pytest.raises(MappingError, match=r"keyboard\.z: unknown action 'fly'"):
        load_mapping(bad)


def test_menu_is_an_edge_and_triggers_are_skills():
    mapper = GamepadMapper(MAPPING)
    idle = GamepadState([0.0, 0.0, -1.0, 0.0, 0.0, -1.0], [0] * 15, [(0, 0)])
    pressed = GamepadState([0.0, 0.0, 0.9, 0.0, 0.0, -1.0], [0] * 7 + [1] + [0] * 7, [(0, 0)])
    assert not mapper.command(idle).menu_pressed
    first = mapper.command(pressed)
    assert first.menu_pressed and first.skills == frozenset({"skill_l2"})
    assert not mapper.command(pressed).menu_pressed  # held, not pressed again


def test_virtual_controller_drives_the_table4_actions(joystick):
    source = JoystickInput(MAPPING, index=joystick.index)
    joystick.axis(1, -1.0)   # left stick fully up: walk forward at the mapped speed
    joystick.axis(0, 0.56)   # left stick half right (after the 0.12 dead zone): walk right at half speed
    joystick.axis(3, 0.05)   # right stick inside the dead zone: no turning
    joystick.hat(0, 0, 1)    # D-pad up: lean (waist roll +)
    joystick.button(3, True)  # Y: look up
    joystick.button(4, True)  # L1: skill
    cmd = source.poll()
    np.testing.assert_allclose(cmd.walk, [0.15, -0.05, 0.0], atol=2e-4)
    np.testing.assert_allclose(cmd.waist_rate, [0.3, 0.0])
    np.testing.assert_allclose(cmd.neck_rate, [0.6, 0.0])
    assert cmd.skills == frozenset({"skill_l1"}) and not cmd.menu_pressed
    joystick.button(7, True)
    assert source.poll().menu_pressed
    assert not source.poll().menu_pressed


def test_keyboard_gives_the_same_actions():
    source = KeyboardInput(MAPPING)
    pg = source.pygame
    for key in (pg.K_w, pg.K_q, pg.K_j):
        pg.event.post(pg.event.Event(pg.KEYDOWN, key=key, mod=0, unicode="", scancode=0))
    cmd = source.poll()
    np.testing.assert_allclose(cmd.walk, [0.15, 0.0, 0.6])
    np.testing.assert_allclose(cmd.neck_rate, [0.0, 0.6])
    pg.event.post(pg.event.Event(pg.KEYUP, key=pg.K_w, mod=0, unicode="", scancode=0))
    np.testing.assert_allclose(source.poll().walk, [0.0, 0.0, 0.6])


@pytest.mark.slow
def test_virtual_controller_walks_the_simulated_robot_and_records_an_episode(joystick, tmp_path):
    from toddlerbot.datasets.episode import resample
    from toddlerbot.datasets.lerobot_reader import load_dataset
    from toddlerbot.datasets.lerobot_writer import write_dataset
    from toddlerbot.policies import make_policy
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.runtime.runner import RunObserver, run_policy
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot
    from toddlerbot.tasks.space import ManipulationSpace
    from toddlerbot.teleop.recording import EpisodeRecorder
    from toddlerbot.teleop.session import TeleopSession

    description = RobotDescription.load(variant="gripper")
    robot = MuJoCoRobot(description)
    space = ManipulationSpace.of(description)
    recorder = EpisodeRecorder("walk forward", space)
    messages: list[str] = []
    session = TeleopSession(robot, JoystickInput(MAPPING, joystick.index), make_policy("walk-zmp", robot),
                            on_menu=recorder.toggle, log=messages.append)

    class Operator(RunObserver):
        """Moves the virtual controller between steps: Menu for step 0, then the stick forward and the D-pad left
        for 0.5 s, for 150 steps; then Menu again."""

        def on_step(self, step) -> None:
            if step.index == 0:
                joystick.button(7, False)
                joystick.axis(1, -0.6)     # left stick forward
                joystick.hat(0, -1, 0)     # D-pad left for 0.5 s: twist the waist by 0.4 rad/s x 0.5 s
            elif step.index == 25:
                joystick.hat(0, 0, 0)
            elif step.index == 150:
                joystick.axis(1, 0.0)
                joystick.button(7, True)   # Menu: episode ends

    start = robot.base_pos  # the start state run_policy's reset puts it in
    joystick.button(7, True)   # Menu: episode starts
    run_policy(robot, session, seconds=152 * robot.control_dt, observers=[recorder, Operator()],
               stop_on_fall=False)
    moved = robot.base_pos - start
    assert not robot.fallen
    assert moved[0] > 0.05, moved
    assert session.neck_waist[3] == pytest.approx(0.2, abs=0.01)
    assert messages == ["episode 0 started", "episode 0 ended (151 steps)"]
    episode = recorder.episodes[0]
    assert episode.state.shape == (151, space.dim)
    root = write_dataset(tmp_path / "teleop", [resample(episode, 10)], space.names, 10, raw_episodes=[episode])
    ds = load_dataset(root)
    assert len(ds) == 31 and ds.n_episodes == 1


def test_leader_arms_drive_the_simulated_pick_robot_and_staleness_is_reported():
    pytest.importorskip("zmq")
    import socket
    import time

    from toddlerbot.runtime.runner import RunObserver, run_policy
    from toddlerbot.tasks.pick import PickTask
    from toddlerbot.teleop.follower import ArmFollower
    from toddlerbot.teleop.gamepad import TeleopCommand
    from toddlerbot.teleop.link import LinkPublisher, LinkSubscriber
    from toddlerbot.teleop.session import TeleopSession

    class Idle:
        def poll(self) -> TeleopCommand:
            return TeleopCommand()

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        endpoint = f"tcp://127.0.0.1:{s.getsockname()[1]}"
    task = PickTask()
    robot = task.robot
    publisher, subscriber = LinkPublisher(endpoint), LinkSubscriber(endpoint)
    follower = ArmFollower(robot.motor_names, task.space.names)
    messages: list[str] = []
    session = TeleopSession(robot, Idle(), leader=(subscriber, follower), log=messages.append)
    goal = robot.reset().motor_pos[task.space.indices].copy()  # where run_policy's reset puts the arms
    elbow = task.space.names.index("right_elbow_roll")
    goal[elbow] += 0.4
    motor = task.space.indices[elbow]

    class Leader(RunObserver):
        """The leader: sends `goal` before each of the first 12 steps (0.4 rad at 0.05 rad per step: reached after
        8), then goes quiet."""

        def on_start(self, robot, policy, obs) -> None:
            deadline = time.monotonic() + 3
            while subscriber.poll() is None and time.monotonic() < deadline:
                publisher.send(task.space.names, goal)
                time.sleep(0.01)
            publisher.send(task.space.names, goal)

        def on_step(self, step) -> None:
            if step.index < 11:
                publisher.send(task.space.names, goal)
            elif step.index == 11:
                self.reached = session.arm_targets[motor]
                time.sleep(0.05)  # a loaded machine may deliver the last message late: let the next step take it
            elif step.index == 12:
                time.sleep(0.25)  # the leader goes quiet

    leader = Leader()
    try:
        run_policy(robot, session, seconds=14 * robot.control_dt, observers=[leader], stop_on_fall=False)
        assert leader.reached == pytest.approx(goal[elbow], abs=1e-9)
        assert follower.holding
        assert messages[0] == "arms: following leader"
        assert messages[-1].startswith("arms: leader stale") and messages[-1].endswith("holding last safe targets")
    finally:
        publisher.close()
        subscriber.close()
