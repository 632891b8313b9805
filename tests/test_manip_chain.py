"""Skill chaining (issue 14): chain files, the wagon chain in sim, chains on teleop buttons, on a RealRobot."""

from __future__ import annotations

import dataclasses
import textwrap

import numpy as np
import pytest

from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.runner import RunObserver, run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.skills.runner import ChainRunner
from toddlerbot.skills.spec import ChainFileError, load_chain
from toddlerbot.tasks.predicates import Context, GraspedParams, PredicateError, holds
from toddlerbot.tasks.scenes import scene_model

DESCRIPTION = RobotDescription.load(variant="gripper")
GROUPS = tuple(DESCRIPTION.groups)


def _chain_file(tmp_path, body: str):
    path = tmp_path / "c.yaml"
    path.write_text(textwrap.dedent(body))
    return path


WAGON_SEEDS = tuple(range(8))
"""A rate over a few seeds keeps CI under a minute; benchmarks/bench_chain.py measures 20 (docs/manipulation.md).
With walk-rl symmetric (2026-11-27) the scripted chain succeeds on 20/20 seeds on an AVX-512 VM; with the policy
alone it was 17/20 on one VM and 6/8 on this one (the left hand let go). The bar is 6 of 8: at a rate of 0.95 it
fails one run in 170."""
WAGON_BAR = 6


@pytest.fixture(scope="module")
def wagon_runs():
    from toddlerbot.skills.sim_run import run_in_sim

    chain = load_chain("wagon", GROUPS).with_scripted_grasps()  # (the chain's own, the dp grasp: test_dp_wagon)
    return [run_in_sim(chain, seed, description=DESCRIPTION).as_json() for seed in WAGON_SEEDS]


def test_wagon_chain_grasps_the_handle_then_pushes_the_wagon_on_most_seeds(wagon_runs):
    succeeded = [out for out in wagon_runs if out["success"]]
    assert len(succeeded) >= WAGON_BAR  # walking and grasping are chaotic: a rate, with margin
    for out in succeeded:
        assert out["failure"] is None and out["wagon_displacement_m"] >= 0.5
        assert out["checks"] == {"moved": True, "grasped": True, "upright": True}  # still pinching, not fallen
    for out in wagon_runs:
        assert out["grasp_by"] == "scripted (no checkpoint named)"
        # grasp ends once the closing command is complete (approach 1.5 + reach 1.5 + close 0.8 s) and the pads pinch
        # (the fingers reach the bar after the command: 4.04-4.06 s measured)
        assert 3.8 <= out["switch_time_s"] <= 4.2
        assert [(s["from"], s["to"]) for s in out["switches"]] == [("grasp", "settle"), ("settle", "push")]
        assert out["switches"][1]["time_s"] == pytest.approx(out["switch_time_s"] + 0.4, abs=0.021)


def test_the_wagon_grip_holds_the_handle_with_margin_through_the_push(wagon_runs):
    # Over 20 seeds with walk-zmp pushing (docs/manipulation.md): the weaker pad at 12.3 N or more, the handle slides
    # at most 2.7 mm along the fingers, each grasp point 38 mm or more from the handle's end; walk-rl symmetric (the
    # chain's push now): 12.7 N or more, slides of at most 4.3 mm (the policy alone slid it 6-8 mm, up to the pads'
    # end 11.5 mm past the grasp point, where a hand let go). Before the handle's rigid contact: pads at 0-1.5 N and
    # slides of 7-32 mm.
    held = [out["grip"] for out in wagon_runs if out["success"]]
    assert len(held) >= WAGON_BAR
    for grip in held:
        assert set(grip) == {"left", "right"}
        for g in grip.values():
            assert g["min_force_n"] >= 10.5 and g["slide_mm"] <= 8.0
            assert g["to_end_mm"] >= 20.0  # both pads (1.8 cm either side of the grasp point) wholly on the bar


@pytest.mark.parametrize("body,message", [
    ("scene: wagon\nskills: []\n", "skills: expected a non-empty list of skills, got []"),
    ("scene: moon\nskills: [{name: a, kind: hold, until: {after: 1}}]\n", "scene: expected one of pick, wagon"),
    ("scene: wagon\nskills: [{name: a, kind: fly, until: {after: 1}}]\n", "skill a: kind: expected one of"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: -1}}]\n",
     "skill a: until.after: expected a positive number of seconds, got -1"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1, button: l1}}]\n",
     "skill a: until: expected exactly one of after, predicate, button"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {button: x9}}]\n",
     "skill a: until.button: expected one of l1, r1, l2, r2, got 'x9'"),
    ("scene: wagon\nskills: [{name: a, kind: hold, hold: [tail], until: {after: 1}}]\n",
     "skill a: hold: expected a list of motor groups"),
    ("scene: wagon\nskills: [{name: a, kind: walk, command: [0.1, 0], until: {after: 1}}]\n",
     "skill a: command: expected"),
    ("scene: wagon\nskills: [{name: a, kind: walk, speed: 2, until: {after: 1}}]\n",
     "skill a: parameters: unknown field 'speed'"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {predicate: grasped}}]\n",
     "skill a: until: target: required"),
    ("scene: wagon\nskills: [{name: a, kind: scripted_grasp, target: h, pitch: fast, until: {after: 1}}]\n",
     "skill a: pitch: expected float, got 'fast'"),
    ("scene: wagon\nskills: [{name: a, kind: scripted_grasp, target: h, arm_kp_scale: 5, until: {after: 1}}]\n",
     "skill a: arm_kp_scale: expected a number in [1, 3], got 5.0"),
    ("scene: pick\nskills: [{name: a, kind: dp, checkpoint: pick, threads: 0, until: {after: 1}}]\n",
     "skill a: threads: expected a positive number of threads, got 0"),
    ("scene: wagon\nskills: [{name: a, kind: pose, motors: {neck_pitch_drive: down}, until: {after: 1}}]\n",
     "skill a: motors.neck_pitch_drive: expected float, got 'down'"),
    ("scene: wagon\nskills: [{name: a, kind: pose, motors: {}, until: {after: 1}}]\n",
     "skill a: motors, grip, home: expected motor angles (name: rad), a grip fraction or groups to move home"),
    ("scene: wagon\nskills: [{name: a, kind: pose, grip: 1.5, until: {after: 1}}]\n",
     "skill a: grip: expected a fraction of the grippers' range in [0, 1], got 1.5"),
    ("scene: wagon\nskills: [{name: a, kind: pose, motors: {neck_pitch_drive: -0.9}, seconds: 0, until: {after: 1}}]\n",
     "skill a: seconds: expected a positive duration, got 0.0"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}, retry: {times: 1}}]\n",
     "skill a: retry: a retry follows the skill's timeout, and it has none"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}, timeout: 2, retry: {times: 0}}]\n",
     "skill a: retry.times: expected a whole number in [1, 10], got 0"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}, timeout: 2, retry: {times: 1, back_off: [x]}}]\n",
     "skill a: retry.back_off: expected a list of the chain's recovery skills (none declared), got ['x']"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}, recover: {lost: {predicate: holding}, "
     "resume: b, times: 1}}, {name: b, kind: hold, until: {after: 1}}]\n",
     "skill a: recover.resume: expected one of a, got 'b'"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}, recover: {lost: {after: 1}, resume: a, "
     "times: 1}}]\n", "skill a: recover.lost: expected {predicate: NAME, ...parameters}"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}, recover: {lost: {predicate: holding, "
     "min_torque: -1}, resume: a, times: 1}}]\n", "skill a: recover.lost: min_torque: expected a positive torque"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}, recover: {lost: {predicate: holding}, "
     "for: -1, resume: a, times: 1}}]\n", "skill a: recover.for: expected seconds in [0, 60], got -1"),
    ("scene: wagon\nskills: [{name: a, kind: hold, until: {after: 1}}]\nrecovery: [{name: r, kind: hold, "
     "until: {after: 1}, retry: {times: 1}}]\n", "recovery skill r: retry: only the chain's skills retry or recover"),
    ("scene: wagon\nskills: [{name: r, kind: hold, until: {after: 1}}]\nrecovery: [{name: r, kind: hold, "
     "until: {after: 1}}]\n", "skill r: name: used twice"),
])
def test_bad_chain_files_get_one_line_errors_naming_file_skill_and_field(tmp_path, body, message):
    path = _chain_file(tmp_path, body)
    with pytest.raises(ChainFileError) as err:
        load_chain(path, GROUPS)
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"{path}: ") and message in text


def test_grasped_on_hardware_is_a_gripper_stalled_short_of_its_closed_target():
    d = DESCRIPTION
    left, right = (d.motor_names.index(f"{s}_gripper_drive") for s in ("left", "right"))
    params = GraspedParams("wagon_handle", "both", closed_fraction=0.8, stall_error=0.15)
    closed = d.motor_range[left, 1] * 0.85
    targets = d.home_motor_pos.copy()
    targets[[left, right]] = closed
    robot = MuJoCoRobot(d)
    obs = robot.reset()

    def grasped(pos_left: float, pos_right: float, t: np.ndarray = targets) -> bool:
        pos = obs.motor_pos.copy()
        pos[[left, right]] = pos_left, pos_right
        return holds("grasped", params, Context(robot, _with_pos(obs, pos), t, probe=None))

    assert grasped(closed - 0.4, closed - 0.3)          # both stalled 0.3-0.4 rad short: holding the handle
    assert not grasped(closed - 0.4, closed - 0.05)      # right reached its target: nothing in it
    open_targets = targets.copy()
    open_targets[[left, right]] = d.motor_range[left, 1] * 0.5
    assert not grasped(0.0, 0.0, open_targets)           # commanded only half closed: not a grasp yet
    either = GraspedParams("wagon_handle", "either", closed_fraction=0.8, stall_error=0.15)
    pos = obs.motor_pos.copy()
    pos[[left, right]] = closed - 0.4, closed
    assert holds("grasped", either, Context(robot, _with_pos(obs, pos), targets, probe=None))


def test_upright_is_the_imu_tilted_less_than_max_tilt_in_sim_and_on_hardware():
    from dataclasses import replace

    from toddlerbot.tasks.predicates import UprightParams

    robot = MuJoCoRobot(DESCRIPTION)
    obs = robot.reset()
    params = UprightParams(max_tilt=0.5)

    def upright(angle: float, axis: np.ndarray) -> bool:
        quat = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
        return holds("upright", params, Context(robot, replace(obs, imu_quat=quat), obs.motor_pos, probe=None))

    pitch, roll, yaw = np.eye(3)[1], np.eye(3)[0], np.eye(3)[2]
    assert upright(0.0, pitch) and upright(0.45, pitch) and upright(-0.45, roll)
    assert not upright(0.55, pitch) and not upright(-0.55, roll) and not upright(1.6, pitch)  # fallen
    assert upright(2.0, yaw)  # heading is not tilt


def test_lifted_is_a_body_risen_at_least_at_least_since_the_chain_started_in_sim_only():
    import mujoco

    from toddlerbot.tasks.predicates import LiftedParams, check_available
    from toddlerbot.tasks.probe import SceneProbe

    model = scene_model(DESCRIPTION, "pick")
    robot = MuJoCoRobot(DESCRIPTION, model=model)
    obs = robot.reset()
    probe = SceneProbe(model, robot.data)
    probe.mark()  # as the runner does when the chain starts
    adr = model.joint("cube").qposadr[0]
    rest = robot.data.qpos[adr : adr + 3].copy()
    params = LiftedParams(body="cube", at_least=0.03)

    def lifted(dx: float, dz: float) -> bool:
        robot.data.qpos[adr : adr + 3] = rest + np.array([dx, 0.0, dz])
        mujoco.mj_forward(model, robot.data)
        return holds("lifted", params, Context(robot, obs, obs.motor_pos, probe))

    assert not lifted(0.0, 0.0) and not lifted(0.1, 0.0)  # at rest, or pushed along the table
    assert not lifted(0.0, 0.029) and not lifted(0.0, -0.05)  # not high enough, or fallen off the table
    assert lifted(0.0, 0.031) and lifted(0.05, 0.1)
    assert probe.rise("cube") == pytest.approx(0.1, abs=1e-9)
    with pytest.raises(PredicateError, match="predicate 'lifted' needs the simulator"):
        check_available("lifted", on_hardware=True, where="c.yaml: skill pick: until")


def _with_pos(obs, pos):
    from dataclasses import replace

    return replace(obs, motor_pos=pos)


def test_a_sim_only_predicate_on_hardware_is_a_one_line_error(tmp_path):
    path = _chain_file(tmp_path, """\
        scene: wagon
        skills:
          - {name: push, kind: walk, command: [0.1, 0, 0], until: {predicate: moved, body: wagon, at_least: 0.5}}
        """)
    chain = load_chain(path, GROUPS)
    robot = MuJoCoRobot(DESCRIPTION)  # no scene probe given: the runner sees only the Robot, as on hardware
    with pytest.raises(PredicateError) as err:
        ChainRunner(chain, robot, scene_model(DESCRIPTION, "wagon"), probe=None)
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"{path}: skill push: until: predicate 'moved' needs the simulator")
    assert "grasped" in text  # names the predicates that do work on hardware


class _Watch(RunObserver):
    """Keeps, after every step of a teleop run, the buttons held, the targets sent and `extra()`; at the start, the
    session's arm targets (teleop's hold) and `at_start()`."""

    def __init__(self, session, extra=lambda: None, at_start=lambda: None) -> None:
        self.session, self.extra, self.at_start, self.steps = session, extra, at_start, []

    def on_start(self, robot, policy, obs) -> None:
        self.robot, self.teleop_targets = robot, self.session.arm_targets.copy()
        self.start = self.at_start()

    def on_step(self, step) -> None:
        self.steps.append((self.session.last_command.skills, self.robot.last_targets.copy(), self.extra()))


def test_holding_l2_in_teleop_runs_the_wagon_chain_and_releasing_returns_to_teleop():
    from toddlerbot.skills.teleop_hook import ChainButtons
    from toddlerbot.tasks.probe import SceneProbe
    from toddlerbot.tasks.scenes import grasp_site
    from toddlerbot.teleop.gamepad import GamepadMapper, GamepadState, KeyboardMapper, TeleopCommand, load_mapping
    from toddlerbot.teleop.session import TeleopSession

    pad = load_mapping()
    assert KeyboardMapper(pad).command({"3"}).skills == frozenset({"skill_l2"})  # keyboard: 3 is L2

    class Trigger:
        """The controller's L2 trigger (axis 2, rest -1) pulled for the first `held` polls, then released."""

        def __init__(self, held: int) -> None:
            self.held, self.polls, self.mapper = held, 0, GamepadMapper(pad)

        def poll(self) -> TeleopCommand:
            self.polls += 1
            l2 = 0.9 if self.polls <= self.held else -1.0
            return self.mapper.command(GamepadState([0.0, 0.0, l2, 0.0, 0.0, -1.0], [0] * 15, [(0, 0)]))

    chain = load_chain("wagon", GROUPS)
    assert chain.button == "l2"
    model = scene_model(DESCRIPTION, "wagon")
    robot = MuJoCoRobot(DESCRIPTION, model=model)  # at its start state, as run_policy's reset puts it
    logs: list[str] = []
    session = TeleopSession(robot, Trigger(held=100), log=logs.append)
    hook = ChainButtons(session, [chain], model, SceneProbe(model, robot.data), log=logs.append)
    site = robot.data.site(grasp_site("right"))
    start = site.xpos.copy()
    handle = robot.data.geom("wagon_handle").xpos.copy()
    watch = _Watch(session, lambda: (hook.runner and hook.runner.status.skill, site.xpos.copy()))
    # 2 s of L2 (the grasp skill's approach, 1.5 s, and part of its reach), then 5 steps released
    run_policy(robot, hook, seconds=105 * robot.control_dt, observers=[watch], stop_on_fall=False)
    held, released = watch.steps[:100], watch.steps[100:]
    assert len(released) == 5
    assert all(skills == frozenset({"skill_l2"}) for skills, _, _ in held)
    _, targets, (skill, grasp_point) = held[-1]
    arms = DESCRIPTION.groups["arm"]
    assert logs == ["chain wagon: started (l2)"] and skill == "grasp"
    assert np.abs(targets[arms] - watch.teleop_targets[arms]).max() > 0.3  # the chain drives the arms
    assert grasp_point[0] - start[0] > 0.04  # right grasp point moved forward towards the handle...
    assert abs(grasp_point[2] - handle[2]) < 0.04  # ...to about its height
    for skills, targets, _ in released:  # released: teleop's held arm targets again
        assert skills == frozenset()
        np.testing.assert_allclose(targets[arms], watch.teleop_targets[arms], atol=1e-9)


def test_holding_l1_in_teleop_on_the_pick_task_runs_the_dp_pick_chain_and_releasing_returns_to_teleop():
    pytest.importorskip("torch")
    from toddlerbot.skills.teleop_hook import with_chains
    from toddlerbot.teleop.gamepad import KeyboardMapper, TeleopCommand, load_mapping
    from toddlerbot.teleop.launch import sim_robot
    from toddlerbot.teleop.session import TeleopSession

    class Keys:
        """Keyboard: nothing for `idle` polls, then "1" (L1) for `held` polls, then nothing."""

        def __init__(self, idle: int, held: int) -> None:
            self.idle, self.held, self.polls, self.mapper = idle, held, 0, KeyboardMapper(load_mapping())

        def poll(self) -> TeleopCommand:
            self.polls += 1
            return self.mapper.command({"1"} if self.idle < self.polls <= self.idle + self.held else set())

    setup = sim_robot("pick", 1000)  # `teleop --task pick --seed 1000`
    robot = setup.robot
    logs: list[str] = []
    session = TeleopSession(robot, Keys(idle=10, held=100), log=logs.append)
    hook = with_chains(session, None, "pick", setup.head_image, log=lambda _: None)  # the pick scene's chains
    assert not setup.walks and {b: c.name for b, c in hook.bound.items()} == {"l1": "pick"}
    hook.log = logs.append
    d = robot.description
    arms, neck = d.groups["arm"], d.motor_names.index("neck_pitch_drive")
    watch = _Watch(session, lambda: (hook.runner, hook.runner and hook.runner.status.skill,
                                     robot.task.grasp_distance()), robot.task.grasp_distance)
    run_policy(robot, hook, seconds=115 * robot.control_dt, observers=[watch], stop_on_fall=False)
    idle, held, released = watch.steps[:10], watch.steps[10:110], watch.steps[110:]
    assert len(released) == 5
    for _, targets, _ in idle:  # teleop holds the task's start pose, the head looking down at the table
        assert targets[neck] == pytest.approx(robot.task.config.neck_pitch, abs=1e-9)
    moved = 0.0
    for _, targets, _ in held:  # 2 s of L1: the policy reaches for the cube
        moved = max(moved, float(np.abs(targets[arms] - watch.teleop_targets[arms]).max()))
        assert targets[neck] == pytest.approx(robot.task.config.neck_pitch, abs=1e-9)
    runner, skill_name, distance = held[-1][2]
    skill = runner.skills[0]
    assert logs == ["chain pick: started (l1)"] and skill_name == "pick"
    assert skill.by == "dp (pick.pt)"
    status = skill.live.status
    # chunks asked for every 25 steps, each used from 15 steps later: 4 in 100 steps (measured 4, arm 0.82 rad off
    # teleop's targets, grasp point 0.101 m -> 0.012 m from the cube)
    assert status.chunks_used >= 3 and status.failures == 0 and status.camera_misses == 0
    assert moved > 0.3  # the policy's chunks, not teleop's hold, drove the arm...
    assert distance < watch.start - 0.05  # ...to the cube
    for _, targets, _ in released:  # released: teleop's held arm targets again
        np.testing.assert_allclose(targets[arms], watch.teleop_targets[arms], atol=1e-9)


def test_a_chain_that_cannot_start_in_teleop_is_one_log_line_and_teleop_goes_on(tmp_path):
    from toddlerbot.skills.teleop_hook import ChainButtons
    from toddlerbot.tasks.probe import SceneProbe
    from toddlerbot.teleop.gamepad import TeleopCommand
    from toddlerbot.teleop.session import TeleopSession

    broken = tmp_path / "broken.pt"  # named and present, so the chain file is read; torch cannot load it
    broken.write_bytes(b"not a torch checkpoint")
    chain = load_chain(_chain_file(tmp_path, f"""\
        scene: pick
        button: r1
        skills: [{{name: reach, kind: dp, checkpoint: {broken}, until: {{after: 1}}}}]
        """), GROUPS)

    class R1:
        def poll(self) -> TeleopCommand:
            return TeleopCommand(skills=frozenset({"skill_r1"}))

    model = scene_model(DESCRIPTION, "pick")
    robot = MuJoCoRobot(DESCRIPTION, model=model)
    logs: list[str] = []
    session = TeleopSession(robot, R1(), log=logs.append)
    hook = ChainButtons(session, [chain], model, SceneProbe(model, robot.data), log=logs.append)
    watch = _Watch(session, lambda: session.arm_targets.copy())
    run_policy(robot, hook, seconds=3 * robot.control_dt, observers=[watch], stop_on_fall=False)
    arms = DESCRIPTION.groups["arm"]
    assert len(watch.steps) == 3
    for _, targets, teleop_targets in watch.steps:  # held: refused once, not retried every step; teleop's go out
        np.testing.assert_allclose(targets[arms], teleop_targets[arms], atol=1e-9)
    assert len(logs) == 1 and logs[0].startswith("chain c: cannot start: ") and "broken.pt" in logs[0]
    assert "\n" not in logs[0]


@pytest.mark.realtime
def test_a_chain_runs_on_a_real_robot_against_the_emulator(tmp_path):
    pytest.importorskip("dynamixel_sdk")
    from hw_support import emulated
    from toddlerbot.hardware.calibration import Calibration, spec_label
    from toddlerbot.hardware.real_robot import RealRobot
    from toddlerbot.skills.robot_run import run_on_robot

    path = _chain_file(tmp_path, """\
        scene: wagon
        skills:
          - name: grasp
            kind: scripted_grasp
            target: wagon_handle
            target_pos: [0.14, 0.0, 0.26]
            approach_s: 0.3
            reach_s: 0.3
            close_s: 0.2
            hold: [leg]
            until: {after: 0.9}
          - {name: wait, kind: hold, until: {button: l1}, timeout: 5}
          - {name: push, kind: walk, command: [0.1, 0, 0], hold: [arm, gripper], until: {after: 0.3}}
        """)
    chain = load_chain(path, GROUPS)
    sent: list[np.ndarray] = []

    class Recording(RealRobot):
        def _apply(self, motor_targets, kp, kd):
            sent.append(motor_targets.copy())
            return super()._apply(motor_targets, kp, kd)

    calls = 0

    def buttons() -> frozenset[str]:
        nonlocal calls
        calls += 1
        return frozenset({"l1"}) if calls > 70 else frozenset()  # L1 pressed about 1.4 s in

    with emulated(DESCRIPTION, offsets_seed=3) as (emu, port):
        calibration = Calibration("tb", spec_label(DESCRIPTION), {m.name: m.mounting_offset for m in emu.motors})
        robot = Recording(DESCRIPTION, port, calibration, reset_duration=0.2)
        status = run_on_robot(chain, robot, buttons)
        torque_after = [m.torque_on for m in emu.motors]
    assert status.failure is None and status.done
    (a, b, t_grasp), (c, d, t_button) = status.switches
    assert (a, b, c, d) == ("grasp", "wait", "wait", "push")
    assert 0.9 <= t_grasp <= 1.1  # after: 0.9 s of robot time
    assert t_button > t_grasp  # the wait skill ended only when L1 came
    targets = np.array(sent)
    lo, hi = DESCRIPTION.motor_range.T
    assert np.isfinite(targets).all() and (targets >= lo - 1e-9).all() and (targets <= hi + 1e-9).all()
    grippers = DESCRIPTION.groups["gripper"]
    assert targets[:, grippers].max() > 0.8 * hi[grippers].min()  # the grasp closed the grippers...
    walk_steps = round(0.3 / robot.control_dt)
    held = targets[-walk_steps:, grippers]
    assert len(sent) > walk_steps and np.abs(held - targets[-walk_steps - 1, grippers]).max() == 0.0  # ...held
    assert not any(torque_after)


def test_chain_run_reports_a_bad_chain_file_in_one_line(tmp_path):
    import subprocess
    import sys

    path = _chain_file(tmp_path, "scene: wagon\nskills: [{name: a, kind: hold, until: {after: 0}}]\n")
    proc = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", "chain", "run", "wagon", "--chain", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: skill a: until.after: expected a positive number of seconds" in lines[0]


def test_a_dp_skill_drives_the_arms_with_a_shipped_checkpoint(tmp_path):
    pytest.importorskip("torch")
    from toddlerbot.tasks.camera import HeadCamera
    from toddlerbot.tasks.probe import SceneProbe

    chain = load_chain(_chain_file(tmp_path, """\
        scene: pick
        skills:
          - {name: reach, kind: dp, checkpoint: pick, until: {after: 1.5}}
        """), GROUPS)
    model = scene_model(DESCRIPTION, "pick")
    robot = MuJoCoRobot(DESCRIPTION, model=model)
    camera = HeadCamera(model, robot.data, DESCRIPTION.handles.head_camera)
    home = DESCRIPTION.home_motor_pos
    arms = DESCRIPTION.groups["arm"]
    runner = ChainRunner(chain, robot, model, SceneProbe(model, robot.data), camera.image, start_targets=home)

    class Reach(RunObserver):
        moved = 0.0

        def on_step(self, step) -> None:
            self.moved = max(self.moved, float(np.abs(step.action.motor_targets[arms] - home[arms]).max()))

    reach = Reach()
    try:
        result = run_policy(robot, runner, seconds=5.0, observers=[reach], stop_on_fall=False)
    finally:
        camera.close()
    assert result.stopped_by == "policy"  # the chain ended, not the 5 s
    assert runner.status.failure is None and runner.skills[0].by == "dp (pick.pt)"
    assert runner.skills[0].live.status.chunks_used >= 2 and runner.skills[0].live.status.failures == 0
    assert reach.moved > 0.05  # the policy's chunks, not a hold, drove the arms
    assert robot.observe().time == pytest.approx(1.5, abs=0.021)


def test_the_shipped_pick_chain_lifts_the_cube_with_the_dp_checkpoint_and_holds_it():
    pytest.importorskip("torch")
    from toddlerbot.skills.sim_run import run_in_sim

    chain = load_chain("pick", GROUPS)
    assert chain.button == "l1" and [s.kind for s in chain.skills] == ["dp", "hold"]
    out = run_in_sim(chain, 1000, description=DESCRIPTION).as_json()  # `chain run pick --seed 1000 --json`
    assert out["success"] and out["failure"] is None and out["checks"] == {"lifted": True, "grasped": True}
    assert out["pick_by"] == "dp (pick.pt)" and out["driven_by"] == {"pick": "dp (pick.pt)", "hold": "hold"}
    # the cube is 3 cm up at 3.88 s (`dp eval` on this seed: success, 1 s later, at 4.9 s); held for 1 s more
    assert 3.0 <= out["switch_time_s"] <= 5.0
    assert out["sim_seconds"] == pytest.approx(out["switch_time_s"] + 1, abs=0.03)
    assert out["cube_lift_m"] >= 0.03  # measured 0.044 m
    dp = out["dp"]["pick"]
    assert dp["chunks_used"] >= 7 and dp["failures"] == 0 and dp["camera_misses"] == 0


def test_on_hardware_the_grasp_aims_at_the_handle_where_the_scene_layout_puts_it():
    from toddlerbot.tasks.scenes import WagonLayout

    model = scene_model(DESCRIPTION, "wagon")
    robot = MuJoCoRobot(DESCRIPTION, model=model)  # stands in for a RealRobot: no probe, so no sensed scene
    runner = ChainRunner(load_chain("wagon", GROUPS), robot, model, probe=None)
    grasp = runner.skills[0]
    assert grasp.by == "scripted (no head camera for wagon.pt)"  # the shipped policy needs the camera
    layout = WagonLayout()
    np.testing.assert_allclose(grasp._bar(), [layout.handle_x, 0.0, layout.handle_height], atol=1e-9)


def test_a_pose_skill_naming_an_unknown_motor_is_one_line(tmp_path):
    from toddlerbot.errors import ToddlerbotError

    path = _chain_file(tmp_path, "scene: wagon\nskills: [{name: a, kind: pose, motors: {neck_tilt: -0.9}, "
                                 "until: {after: 1}}]\n")
    chain = load_chain(path, GROUPS)
    robot = MuJoCoRobot(DESCRIPTION)
    with pytest.raises(ToddlerbotError, match=r"^pose skill: neck_tilt: not motors of toddlerbot") as err:
        ChainRunner(chain, robot, robot.model)
    assert "\n" not in str(err.value)


def test_a_pose_skill_squeezes_the_grippers_to_a_fraction_of_their_range_and_keeps_the_rest():
    """e.g. a settle after a learned grasp whose command stopped at 0.72 of the range: closed to 0.78."""
    from toddlerbot.skills.library import PoseParams, PoseSkill, SkillEnv

    robot = MuJoCoRobot(DESCRIPTION)
    env = SkillEnv(robot, robot.model, lambda: robot.data.qpos, None, lambda name: np.zeros(3), None, True)
    skill = PoseSkill(env, PoseParams(grip=0.78, seconds=0.3))
    grippers = list(DESCRIPTION.groups["gripper"])
    lo, hi = DESCRIPTION.motor_range[grippers].T
    start = DESCRIPTION.home_motor_pos + 0.01
    start[grippers] = lo + 0.72 * (hi - lo)
    skill.start(robot.observe(), start)
    halfway, _ = skill.act(robot.observe(), 0.15)
    end, kp = skill.act(robot.observe(), 0.3)
    np.testing.assert_allclose((end[grippers] - lo) / (hi - lo), 0.78, atol=1e-12)
    np.testing.assert_allclose((halfway[grippers] - lo) / (hi - lo), 0.75, atol=1e-12)  # minimum jerk: half at half
    others = np.setdiff1d(np.arange(len(start)), grippers)
    np.testing.assert_array_equal(end[others], start[others])
    np.testing.assert_array_equal(kp, DESCRIPTION.default_kp)


def test_a_chain_seeds_its_learned_skills_sampling_noise_with_the_runs_seed(monkeypatch):
    """`chain run wagon --seed S`: the dp grasp's diffusion noise is seeded S, so seeded runs are independent trials
    (with one stream seeded 0 for every run, 4/10 succeeded; seeded by the run, 18/20: docs/manipulation.md)."""
    pytest.importorskip("torch")
    import dataclasses

    import toddlerbot.dp.live as live
    from toddlerbot.tasks.probe import SceneProbe

    seeds = []
    monkeypatch.setattr(live, "load_live_policy", lambda *args, seed, **kwargs: seeds.append(seed))
    model = scene_model(DESCRIPTION, "wagon")
    robot = MuJoCoRobot(DESCRIPTION, model=model)
    probe = SceneProbe(model, robot.data)
    chain = load_chain("wagon", GROUPS)
    ChainRunner(chain, robot, model, probe, lambda: np.zeros((96, 96, 3), np.uint8), seed=1234)
    ChainRunner(chain, robot, model, probe, lambda: np.zeros((96, 96, 3), np.uint8))
    pinned = dataclasses.replace(load_chain("pick", GROUPS), scene="wagon")
    pinned = dataclasses.replace(pinned, skills=(dataclasses.replace(
        pinned.skills[0], params=dataclasses.replace(pinned.skills[0].params, seed=7)),))
    ChainRunner(pinned, robot, model, probe, lambda: np.zeros((96, 96, 3), np.uint8), seed=1234)
    assert seeds == [1234, 0, 7]  # the run's seed, 0 by default, a chain file's own seed first


def test_without_torch_the_chains_grasp_falls_back_to_the_script_and_says_why(monkeypatch):
    import toddlerbot.skills.library as library
    from toddlerbot.tasks.probe import SceneProbe

    monkeypatch.setattr(library, "have_torch", lambda: False)
    model = scene_model(DESCRIPTION, "wagon")
    robot = MuJoCoRobot(DESCRIPTION, model=model)
    runner = ChainRunner(load_chain("wagon", GROUPS), robot, model, SceneProbe(model, robot.data),
                         lambda: np.zeros((96, 96, 3), np.uint8))
    assert runner.skills[0].by == "scripted (no torch for wagon.pt: pip install 'toddlerbot[dp]')"


@pytest.mark.parametrize(("shipped", "kind", "named", "expected"), [
    ("wagon", "scripted_grasp", "../../../../etc/passwd",
     "checkpoint: no checkpoint is shipped for '../../../../etc/passwd'; expected one of pick, wagon or a .pt file"),
    ("wagon", "scripted_grasp", "missing.pt", "checkpoint: 'missing.pt' is not a file"),
    ("pick", "dp", "../../../../etc/passwd", "checkpoint: no checkpoint is shipped for '../../../../etc/passwd'"),
])
def test_a_named_checkpoint_that_cannot_be_loaded_is_an_error_not_a_fallback(tmp_path, monkeypatch, capsys,
                                                                           shipped, kind, named, expected):
    """The grasp once fell back to its script quietly, and the chain exited 0."""
    from cli_support import one_line_error, run_main
    from toddlerbot.skills.spec import SHIPPED_DIR, ChainFileError

    text = (SHIPPED_DIR / f"{shipped}.yaml").read_text()
    original = f"checkpoint: {shipped}"
    assert text.count(original) == 1 and f"kind: {kind}" in text
    path = _chain_file(tmp_path, text.replace(original, f"checkpoint: {named}"))
    with pytest.raises(ChainFileError) as err:
        load_chain(path, GROUPS)
    assert expected in str(err.value) and str(err.value).startswith(str(path))
    code, _, stderr = run_main(monkeypatch, capsys, "chain", "run", path)
    assert expected in one_line_error(code, stderr)


WALKER_MODULE = '''
import numpy as np

from toddlerbot.locomotion.config import CommandReach
from toddlerbot.policies.base import Policy


class SwayPolicy(Policy):
    """A "walking" policy of one's own: it follows velocity commands by swaying the waist yaw with the yaw rate."""

    name = "sway"
    command_reach = CommandReach(low=(0.0, 0.0, -0.5), high=(0.0, 0.0, 0.5))

    def reset(self, obs):
        pass

    def act(self, obs, command):
        targets = self.robot.description.home_motor_pos.copy()
        targets[self.robot.motor_names.index("waist_drive_1")] += float(self.within_reach(command)[2])
        return self.joint_action(self.transmission.motor_to_joint(targets))
'''


def test_a_chain_walks_with_any_registered_walking_policy(tmp_path, monkeypatch, restored_registries):
    """A policy of one's own (one new file and one registration) drives a chain's walk skill: no list of walking
    policies stands in the way; one that follows no command, or an unknown name, is refused in one line."""
    from toddlerbot.errors import ToddlerbotError
    from toddlerbot.policies import register_policy
    from toddlerbot.skills.sim_run import run_in_sim
    from toddlerbot.skills.spec import ChainFileError

    (tmp_path / "my_walkers.py").write_text(WALKER_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    register_policy("sway", "my_walkers:SwayPolicy")
    chain = load_chain(_chain_file(tmp_path, """\
        scene: wagon
        skills: [{name: turn, kind: walk, policy: sway, command: [0, 0, 0.3], until: {after: 0.6}}]
        """), GROUPS)
    result = run_in_sim(chain, 0, description=DESCRIPTION)
    assert result.success and result.driven_by == {"turn": "sway"} and result.sim_seconds == pytest.approx(0.6)
    with pytest.raises(ChainFileError, match=r"skill turn: policy: expected a registered policy \(.*sway\), got "
                                             r"'moonwalk'"):
        load_chain(_chain_file(tmp_path, "scene: wagon\nskills: [{name: turn, kind: walk, policy: moonwalk, "
                                         "until: {after: 1}}]\n"), GROUPS)
    standing = load_chain(_chain_file(tmp_path, "scene: wagon\nskills: [{name: turn, kind: walk, policy: stand, "
                                                "until: {after: 1}}]\n"), GROUPS)
    with pytest.raises(ToddlerbotError, match=r"^walk skill: policy 'stand' follows no velocity command"):
        run_in_sim(standing, 0, description=DESCRIPTION)


SLIP_FRICTION = 0.05


class _Slip(RunObserver):
    """From `at` s the left hand's grip on the wagon handle turns slippery (its pads take the contact at friction
    `SLIP_FRICTION`; dropping the handle's own friction below ~0.3 makes its stiff pinch blow up numerically, and at
    0.1 the hand slips and catches the handle again), until the chain opens its hands to grasp again. Keeps the left
    pads' force and the gripper torques when the chain noticed."""

    def __init__(self, at: float) -> None:
        self.at, self.restored, self.noticed = at, False, None

    def on_start(self, robot, policy, obs) -> None:
        from toddlerbot.tasks.probe import SceneProbe
        from toddlerbot.tasks.scenes import finger_pads

        self.robot, self.chain, self.probe = robot, policy, SceneProbe(robot.model, robot.data)
        self.pads = [robot.model.geom(p).id for p in finger_pads("left")]
        self.friction = robot.model.geom_friction[self.pads].copy()

    def on_step(self, step) -> None:
        model, status = self.robot.model, self.chain.status
        if self.noticed is None and status.recoveries:
            obs = self.robot.observe()
            grippers = [DESCRIPTION.motor_names.index(f"{s}_gripper_drive") for s in ("left", "right")]
            self.noticed = (self.probe.pad_forces("left", "wagon_handle"), obs.motor_torque[grippers])
        self.restored = self.restored or status.skill == "open"
        slippery = step.obs.time >= self.at and not self.restored
        model.geom_priority[self.pads] = 2 if slippery else 0
        model.geom_friction[self.pads, 0] = SLIP_FRICTION if slippery else self.friction[:, 0]


def test_a_hand_that_lets_go_of_the_handle_mid_push_is_noticed_and_the_chain_grasps_again_and_pushes_on():
    from toddlerbot.skills.sim_run import run_in_sim

    chain = load_chain("wagon", GROUPS).with_scripted_grasps()
    slip = _Slip(at=7.0)  # 2.5 s into the push
    out = run_in_sim(chain, 0, description=DESCRIPTION, disturbances=[slip]).as_json()
    # Measured (seed 0): the left hand let go at once; the chain noticed from its gripper's torque at 7.18 s (7.58 s
    # on a fresh install of 2026-11-29, the same code: the chain is chaotic, so the bound is 1 s), stood,
    # opened, grasped again (the first re-grasp closed on nothing, its retry closed on the handle) and pushed on:
    # wagon moved 0.656 m, both hands on it at the end; 11 s wall. The script's re-grasp is not robust: seed 0 is the
    # one of seeds 0-7 whose push resumes (2 of 8 in the wide variation; docs/manipulation.md, "The wagon scene's
    # declared ranges"), so this checks the declared path, not a rate.
    recover = out["recoveries"][0]
    assert recover["kind"] == "recover" and recover["skill"] == "push" and recover["resume"] == "grasp"
    assert 7.0 < recover["time_s"] < 8.0
    pads, torque = slip.noticed
    assert pads.min() < 1.0 and torque[0] < 0.15 <= torque[1]  # the left hand no longer pinched, the right still held
    names = [(s["from"], s["to"]) for s in out["switches"]]
    assert names[:5] == [("grasp", "settle"), ("settle", "push"), ("push", "stand"), ("stand", "open"),
                         ("open", "grasp")]
    assert names[-2:] == [("grasp", "settle"), ("settle", "push")]  # grasped again, then the push resumed
    assert all(r["kind"] == "retry" and r["skill"] == "grasp" for r in out["recoveries"][1:])
    resumed = out["switches"][-1]["time_s"]
    walked = (recover["time_s"] - out["switches"][1]["time_s"]) + (out["sim_seconds"] - resumed)
    assert walked == pytest.approx(8.0, abs=0.05)  # the push walked its 8 s in all, not 8 s more
    assert out["success"] and out["checks"] == {"moved": True, "grasped": True, "upright": True}


class _HandleAway(RunObserver):
    """The wagon handle takes no contacts until the chain first opens its hands: the first grasp closes on nothing."""

    def on_start(self, robot, policy, obs) -> None:
        self.model, self.chain = robot.model, policy
        self.handle = robot.model.geom("wagon_handle").id
        self.model.geom_contype[self.handle] = self.model.geom_conaffinity[self.handle] = 0

    def on_step(self, step) -> None:
        if self.chain.status.skill == "retract":
            self.model.geom_contype[self.handle] = self.model.geom_conaffinity[self.handle] = 1


def test_a_grasp_that_has_not_closed_in_its_time_is_retried_after_backing_off(tmp_path):
    from toddlerbot.skills.sim_run import run_in_sim

    shipped = load_chain("wagon", GROUPS).with_scripted_grasps()
    grasp_only = dataclasses.replace(shipped, skills=shipped.skills[:2],  # grasp, settle: no push
                                     success=(("grasped", GraspedParams("wagon_handle", "both")),))
    out = run_in_sim(grasp_only, 0, description=DESCRIPTION, disturbances=[_HandleAway()]).as_json()
    # Measured: the first grasp closes on nothing and times out at 6.02 s; the back-off opens the hands (0.4 s) and
    # brings the arms home (1 s), the retry closes on the handle at 11.5 s.
    assert out["recoveries"] == [{"kind": "retry", "skill": "grasp", "resume": "grasp", "time_s": pytest.approx(
        6.02, abs=0.021)}]
    assert [(s["from"], s["to"]) for s in out["switches"]] == [
        ("grasp", "open"), ("open", "retract"), ("retract", "grasp"), ("grasp", "settle")]
    times = [s["time_s"] for s in out["switches"]]
    assert times[1] - times[0] == pytest.approx(0.4, abs=0.021) and times[2] - times[1] == pytest.approx(1.0, abs=0.021)
    assert 3.8 <= times[3] - times[2] <= 4.2  # the retry grasps as the first grasp of a run does
    assert out["switch_time_s"] == times[3] and out["success"]
