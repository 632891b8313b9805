"""MuJoCo backend: observations, safety clamps, instability detection, fall detection."""

import numpy as np
import pytest

from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimulationError
from toddlerbot.sysid.params import catalogue_with_params


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


def test_targets_are_clamped_to_joint_limits(robot):
    targets = np.full(len(robot.motor_names), 100.0)
    clamped = robot.clamp_targets(targets)
    joint = robot.transmission.motor_to_joint(clamped)
    assert np.all(joint <= robot._joint_range[:, 1] + 1e-9)
    assert np.all(clamped <= robot._motor_range[:, 1] + 1e-9)


def test_non_finite_target_stops_with_a_clear_error(robot):
    robot.reset()
    with pytest.raises(SimulationError, match="non-finite"):
        robot.step(np.full(len(robot.motor_names), np.nan))


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
    fitted = MuJoCoRobot(catalogue=catalogue_with_params([params]))
    knee = fitted.model.joint("left_knee_drive")
    assert fitted.model.dof_armature[knee.dofadr[0]] == pytest.approx(0.0031)
    knee_motor = fitted.motor_names.index("left_knee_drive")
    assert fitted.actuator_params[knee_motor].tau_max == pytest.approx(1.23)
