"""Skill chaining (issue 14): chain files, the wagon chain in sim, chains on teleop buttons, on a RealRobot."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from toddlerbot.manipulation.chaining.predicates import Context, GraspedParams, PredicateError, holds
from toddlerbot.manipulation.chaining.runner import ChainRunner
from toddlerbot.manipulation.chaining.spec import ChainFileError, load_chain
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.scenes import scene_model

DESCRIPTION = RobotDescription.load(variant="gripper")
GROUPS = tuple(DESCRIPTION.groups)


def _chain_file(tmp_path, body: str):
    path = tmp_path / "c.yaml"
    path.write_text(textwrap.dedent(body))
    return path


@pytest.mark.parametrize("seed", [0, 1])
def test_wagon_chain_grasps_the_handle_then_pushes_the_wagon(seed):
    from toddlerbot.manipulation.chaining.sim_run import run_in_sim

    result = run_in_sim(load_chain("wagon", GROUPS), seed, description=DESCRIPTION)
    out = result.as_json()
    assert out["success"] is True and result.failure is None
    assert out["wagon_displacement_m"] >= 0.5
    assert out["checks"] == {"moved": True, "grasped": True}  # both grippers still pinch the handle at the end
    assert out["grasp_by"] == "scripted (no checkpoint for task wagon)"
    # grasp ends once the closing command is complete (approach 1.5 + reach 1.5 + close 0.8 s) and the pads pinch
    assert 3.8 <= out["switch_time_s"] <= 4.2
    assert [(s["from"], s["to"]) for s in out["switches"]] == [("grasp", "settle"), ("settle", "push")]
    assert out["switches"][1]["time_s"] == pytest.approx(out["switch_time_s"] + 0.4, abs=0.021)


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
