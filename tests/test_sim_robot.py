"""MuJoCo backend: observations, safety clamps, instability detection, fall detection."""

import numpy as np
import pytest

from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.safety import UnsafeCommandError
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


@pytest.fixture(scope="module")
def robot():
    return MuJoCoRobot()


def test_reset_observation_is_standing_on_both_feet(robot):
    obs = robot.reset()
    first = robot.step(obs.motor_pos)
    assert first.time == pytest.approx(robot.control_dt)
    for _ in range(25):  # let the contacts settle
        obs = robot.step(obs.motor_pos)
    assert obs.foot_contact.tolist() == [True, True]
    assert obs.imu_lin_acc[2] == pytest.approx(9.81, abs=0.5)  # gravity reads +g when standing
    np.testing.assert_allclose(obs.joint_pos, robot.transmission.motor_to_joint(obs.motor_pos))


@pytest.mark.parametrize("value", [100.0, -100.0])
def test_targets_are_clamped_to_both_joint_limits(robot, value):
    description = robot.description
    robot.reset()
    robot.step(np.full(len(robot.motor_names), value))
    sent = robot.last_targets
    joint = robot.transmission.motor_to_joint(sent)
    lower, upper = description.joint_range.T
    assert np.all(joint <= upper + 1e-9) and np.all(joint >= lower - 1e-9)
    assert np.all(sent <= description.motor_range[:, 1] + 1e-9)
    assert np.all(sent >= description.motor_range[:, 0] - 1e-9)
    # each motor sits at one of its own or its output joint's limits, not somewhere inside
    at_limit = np.isclose(sent, description.motor_range[:, 1 if value > 0 else 0]) | np.isclose(
        robot.transmission.inverse @ joint, sent)
    assert at_limit.all()
    ankle = robot.motor_names.index("left_ankle_pitch")
    assert sent[ankle] == pytest.approx(description.motor_range[ankle, 1 if value > 0 else 0])


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_target_is_refused_and_nothing_is_applied(robot, bad):
    robot.reset()
    before = robot._targets.copy()
    targets = robot.observe().motor_pos.copy()
    targets[3] = bad
    with pytest.raises(UnsafeCommandError, match=r"non-finite motor target for 1 motor\(s\) \(waist_drive_2\)"):
        robot.step(targets)
    np.testing.assert_array_equal(robot._targets, before)


def test_non_finite_or_out_of_range_gains_are_refused(robot):
    robot.reset()
    kp = robot.default_kp.copy()
    kp[0] = np.nan
    with pytest.raises(UnsafeCommandError, match="non-finite kp"):
        robot.step(robot.observe().motor_pos, kp=kp)
    kp[0] = 1e6
    with pytest.raises(UnsafeCommandError, match=r"kp for neck_yaw_drive is 1e\+06; expected 0..16383"):
        robot.step(robot.observe().motor_pos, kp=kp)


def test_fall_detector_fires_when_the_robot_goes_limp(robot):
    robot.reset()
    zero = np.zeros(len(robot.motor_names))
    for _ in range(150):  # 3 s without motor stiffness
        robot.step(robot.observe().motor_pos, kp=zero, kd=zero)
        if robot.fallen:
            break
    assert robot.fallen
    robot.set_gains(robot.default_kp, robot.default_kd)


def test_fitted_motor_params_reach_the_simulated_joints_and_actuator_model(tmp_path):
    params = tmp_path / "xm430.json"
    params.write_text('{"motor": "XM430", "actuator": {"armature": 0.0031, "tau_max": 1.23}}')
    fitted = MuJoCoRobot(RobotDescription.load(motor_params=[params]))
    knee = fitted.model.joint("left_knee_drive")
    assert fitted.model.dof_armature[knee.dofadr[0]] == pytest.approx(0.0031)
    knee_motor = fitted.motor_names.index("left_knee_drive")
    assert fitted.description.actuator_params[knee_motor].tau_max == pytest.approx(1.23)


def test_the_same_gains_every_step_keep_the_drive_and_new_gains_replace_it():
    """A policy sending its gains every step (the tasks, dp) costs no rebuild of the actuator arrays; other gains
    do take effect."""
    robot = MuJoCoRobot()
    kp = robot.default_kp * 0.5
    robot.step(robot.description.home_motor_pos, kp=kp)
    drive = robot._drive
    robot.step(robot.description.home_motor_pos, kp=kp.copy())
    assert robot._drive is drive
    robot.step(robot.description.home_motor_pos, kp=kp * 2)
    assert robot._drive is not drive
    np.testing.assert_array_equal(robot._drive.params.kp, robot.description.actuator_arrays(kp * 2,
                                                                                           robot.default_kd).kp)
