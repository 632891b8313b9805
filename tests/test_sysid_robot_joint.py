"""The robot_joint rig: one motor of the fixed-base MuJoCo robot replaying goal positions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.evaluate import evaluate
from toddlerbot.sysid.excitation import Excitation
from toddlerbot.sysid.manifest import Manifest, load_manifest
from toddlerbot.sysid.rigs import RobotJointRig
from toddlerbot.sysid.synthetic import synthesize


def test_robot_joint_step_and_parameter_sensitivity() -> None:
    rig = RobotJointRig(joint="left_elbow_roll")
    motor = default_catalogue()["2XL430"]
    t = np.arange(0, 0.8, 0.005)
    goal = np.where(t < 0.1, 0.0, 0.4)
    runs = synthesize([Excitation("step", 700, t, goal)], rig, motor.actuator)
    q = runs[0].position
    assert abs(q[-1] - 0.4) < np.radians(3)  # the elbow reaches its goal (kp 700 -> 4.7 N*m/rad vs gravity)
    assert np.max(np.abs(np.diff(q[: int(0.1 / 0.005)]))) < 1e-3  # and holds still before the step
    manifest = Manifest(Path("robot.json"), motor, rig, tuple(runs))
    assert evaluate(manifest, motor.actuator).mae_deg < 1e-9  # replaying the same parameters is exact
    slower = motor.actuator.replace(armature=4 * motor.actuator.armature, tau_max=0.5 * motor.actuator.tau_max)
    assert evaluate(manifest, slower).mae_deg > 0.5


def test_robot_joint_motor_must_match(tmp_path: Path) -> None:
    (tmp_path / "r.csv").write_text("time,goal_position,position\n0,0,0\n0.005,0,0\n")
    (tmp_path / "m.json").write_text(json.dumps({"motor": "XC330", "rig": {"type": "robot_joint",
                                                                           "joint": "left_elbow_roll"},
                                                 "logs": [{"file": "r.csv", "kp": 400}]}))
    with pytest.raises(SysIDError, match=r"m.json: robot joint 'left_elbow_roll' is driven by a 2XL430-W250"):
        load_manifest(tmp_path / "m.json")
    (tmp_path / "m.json").write_text(json.dumps({"motor": "XC330", "rig": {"type": "robot_joint", "joint": "nope"},
                                                 "logs": [{"file": "r.csv", "kp": 400}]}))
    with pytest.raises(SysIDError, match=r"'nope' is not a motor joint"):
        load_manifest(tmp_path / "m.json")
