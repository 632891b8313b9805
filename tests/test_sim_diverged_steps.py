"""A control step that diverges (MuJoCo's bad-acceleration reset, or a joint blown up to hundreds of rad/s, as a
hard fall can make it with the spec's 4 solver iterations) is taken again from its start with more iterations
(`sim.actuated.step_one_robot`); one that does not diverge is untouched."""

import mujoco
import numpy as np
import pytest

from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim import actuated
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


@pytest.fixture(scope="module")
def robot():
    return MuJoCoRobot(RobotDescription.load())


def _state(robot):
    m, d = robot.model, robot.data
    state = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, d, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    return state


def test_a_diverged_step_is_taken_again_with_more_iterations_and_a_clean_one_is_not(robot, monkeypatch):
    robot.reset()
    targets = robot.description.home_motor_pos + 0.05
    start = _state(robot)
    calls = []
    clean = actuated.step_actuated

    def diverging_once(models, datas, *args, **kwargs):
        calls.append(models[0].opt.iterations)
        torque = clean(models, datas, *args, **kwargs)
        if len(calls) == 1:  # what MuJoCo leaves after a bad acceleration: the warning, the state reset
            mujoco.mj_resetData(models[0], datas[0])
            datas[0].warning[mujoco.mjtWarning.mjWARN_BADQACC].number = 1
        return torque

    monkeypatch.setattr(actuated, "step_actuated", diverging_once)
    torque, retried = actuated.step_one_robot(robot.model, robot.data, robot._motors, targets, robot._drive, 20)
    assert retried and calls == [4, actuated.RETRY_SOLVER_ITERATIONS]
    assert (robot.model.opt.iterations, robot.model.opt.ls_iterations) == (4, 8)  # the spec's, back
    assert not actuated.diverged(robot.data)
    after_retry = _state(robot)

    monkeypatch.setattr(actuated, "step_actuated", clean)  # the same step, taken at 100 iterations from the start
    mujoco.mj_setState(robot.model, robot.data, start, mujoco.mjtState.mjSTATE_INTEGRATION)
    robot.model.opt.iterations = robot.model.opt.ls_iterations = actuated.RETRY_SOLVER_ITERATIONS
    expected = clean([robot.model], [robot.data], robot._motors, targets[None], robot._drive, 20)[0]
    robot.model.opt.iterations, robot.model.opt.ls_iterations = 4, 8
    np.testing.assert_array_equal(after_retry, _state(robot))
    np.testing.assert_array_equal(torque, expected)

    mujoco.mj_setState(robot.model, robot.data, start, mujoco.mjtState.mjSTATE_INTEGRATION)
    once = clean([robot.model], [robot.data], robot._motors, targets[None], robot._drive, 20)[0]
    plain = _state(robot)
    mujoco.mj_setState(robot.model, robot.data, start, mujoco.mjtState.mjSTATE_INTEGRATION)
    torque, retried = actuated.step_one_robot(robot.model, robot.data, robot._motors, targets, robot._drive, 20)
    assert not retried
    np.testing.assert_array_equal(torque, once)  # a step that does not diverge is exactly step_actuated's
    np.testing.assert_array_equal(_state(robot), plain)


def test_a_blown_up_joint_counts_as_diverged(robot):
    robot.reset()
    assert not actuated.diverged(robot.data)
    robot.data.qvel[10] = 1.5 * actuated.DIVERGED_SPEED
    assert actuated.diverged(robot.data)
    robot.data.qvel[10] = np.nan
    assert actuated.diverged(robot.data)
    robot.reset()


def test_a_step_that_throws_the_robot_with_more_energy_than_its_motors_give_is_taken_again(robot, monkeypatch):
    robot.reset()
    targets = robot.description.home_motor_pos
    calls = []
    clean = actuated.step_actuated

    def throwing_once(models, datas, *args, **kwargs):
        calls.append(models[0].opt.iterations)
        torque = clean(models, datas, *args, **kwargs)
        if len(calls) == 1:  # 3.4 kg thrown up at 4 m/s: 27 J in 20 ms, every joint well under DIVERGED_SPEED
            datas[0].qvel[2] = 4.0
        return torque

    monkeypatch.setattr(actuated, "step_actuated", throwing_once)
    _, retried = actuated.step_one_robot(robot.model, robot.data, robot._motors, targets, robot._drive, 20)
    assert retried and calls == [4, actuated.RETRY_SOLVER_ITERATIONS]
    assert abs(robot.data.qvel[2]) < 0.5
    robot.reset()


def test_a_hard_landing_no_longer_launches_the_fallen_robot():
    """Walk-rl kicked onto its back (get-up trials, seed 62): at the landing four Newton iterations left the torso
    and an elbow 12 mm in the floor and the next step threw the robot 3 m up with every joint under 50 rad/s."""
    from toddlerbot.policies.get_up_trials import fallen_robot

    fallen = fallen_robot(RobotDescription.load(), 62, "back")
    assert fallen.robot.retried_steps >= 1
    assert fallen.robot.torso_height() < 0.15  # lying, settled (it was at 1.08 m, in the air)
    assert np.abs(fallen.robot.base_lin_vel).max() < 0.2
