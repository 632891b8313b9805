"""What a fall does to a run: the shared layer lowers the P gains from the fall's detection until the torso lands
(`robot.fall.FallGuard`, in `Robot.step` for every backend), and a run given a recovery policy hands the fallen
robot to it and goes on with its own policy once the recovery succeeds (`runtime.runner`)."""

from dataclasses import replace

import numpy as np
import pytest

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.fall import FALL_KP_FRACTION, LANDED_S, FallGuard
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.runtime.runner import run_policy

DT = 0.02
UPRIGHT = np.array([1.0, 0.0, 0.0, 0.0])
LYING = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])  # 90 degrees about x
TURNING, STILL = np.array([3.0, 0.0, 0.0]), np.zeros(3)


@pytest.fixture(scope="module")
def description():
    return RobotDescription.load()


class ScriptedRobot(Robot):
    """A robot whose IMU reads a script, one (quaternion, gyro) per step; it has fallen while tilted. It records the
    gains each step sent to the backend."""

    def __init__(self, description, script):
        super().__init__(description, DT)
        self.script, self.sent = script, []
        n = description.n_motors
        self._obs = Observation(0.0, *(np.zeros(n) for _ in range(5)), UPRIGHT, STILL, np.zeros(3), np.zeros(2, bool))

    def reset(self):
        self.last_targets = None
        self._obs = replace(self._obs, time=0.0, imu_quat=UPRIGHT, imu_ang_vel=STILL)
        return self._obs

    def observe(self):
        return self._obs

    def _apply(self, motor_targets, kp, kd):
        self.sent.append(kp)
        quat, gyro = self.script[min(len(self.sent), len(self.script)) - 1]
        self._obs = replace(self._obs, time=len(self.sent) * DT, imu_quat=quat, imu_ang_vel=gyro)
        return self._obs


class HoldHome(Policy):
    name = "hold"

    def __init__(self, robot, done_after=None):
        super().__init__(robot)
        self.resets, self.steps, self.done_after = 0, 0, done_after

    def reset(self, obs):
        self.resets += 1

    def act(self, obs, command):
        self.steps += 1
        q = self.robot.description.home_motor_pos
        return Action(q, self.transmission.matrix @ q)


class Recovery(HoldHome):
    """Gets up after ``steps_needed`` steps of its own, or gives up then."""

    name = "recover"

    def __init__(self, robot, steps_needed, succeeds=True):
        super().__init__(robot)
        self.steps_needed, self.succeeds, self.own_steps = steps_needed, succeeds, 0

    def reset(self, obs):
        super().reset(obs)
        self.own_steps = 0

    def act(self, obs, command):
        self.own_steps += 1
        return super().act(obs, command)

    @property
    def done(self):
        return self.own_steps >= self.steps_needed

    @property
    def succeeded(self):
        return self.succeeds


def test_the_guard_lowers_the_gains_from_the_fall_until_the_landing_and_restores_them_once():
    guard, kp = FallGuard(DT), np.full(3, 800.0)
    landed = round(LANDED_S / DT)
    readings = [(UPRIGHT, TURNING), (LYING, STILL)] + [(LYING, TURNING)] * 3 + [(LYING, STILL)] * landed
    sent = []
    for quat, gyro in readings:
        sent.append(guard.gains(kp, kp))
        guard.update(quat, gyro)
    sent.append(guard.gains(None, kp))  # landed: the asked gains once, explicitly
    sent.append(guard.gains(None, kp))
    lowered = FALL_KP_FRACTION * kp
    # upright and turning (a kick) or lying still (already down): not a fall in progress
    assert [s is kp for s in sent[:3]] == [True, True, True]
    for s in sent[3:3 + 2 + landed]:  # from the first tilted-and-turning reading until the torso is still
        np.testing.assert_allclose(s, lowered)
    np.testing.assert_array_equal(sent[-2], kp)
    assert sent[-1] is None
    with pytest.raises(ValueError, match=r"kp_fraction 0\.0: expected a fraction in \(0, 1\]"):
        FallGuard(DT, 0.0)


def test_every_robot_sends_lowered_gains_while_falling_and_a_reset_forgets_the_fall(description):
    script = [(UPRIGHT, STILL)] * 2 + [(LYING, TURNING)] * 3 + [(LYING, STILL)] * 10
    robot = ScriptedRobot(description, script)
    robot.reset()
    policy = HoldHome(robot)
    run_policy(robot, policy, seconds=len(script) * DT, stop_on_fall=False)
    default = robot.default_kp
    assert robot.sent[:3] == [None, None, None]
    landing = 3 + 2 + round(LANDED_S / DT)  # falling after the 3rd step, turning 2 more, then still until landed
    for kp in robot.sent[3:landing]:
        np.testing.assert_allclose(kp, FALL_KP_FRACTION * default)
    np.testing.assert_array_equal(robot.sent[landing], default)
    assert robot.sent[-1] is None
    robot.fall_guard.falling = True  # as if a run ended mid-fall
    robot.reset()
    robot.step(description.home_motor_pos)
    assert robot.sent[-1] is None and not robot.fall_guard.falling


def test_a_run_with_a_recovery_hands_the_fallen_robot_to_it_and_goes_on(description):
    script = [(UPRIGHT, STILL)] * 10 + [(LYING, STILL)] * 5 + [(UPRIGHT, STILL)] * 30 + [(LYING, STILL)] * 5 \
        + [(UPRIGHT, STILL)] * 100
    robot = ScriptedRobot(description, script)
    walk, get_up = HoldHome(robot), Recovery(robot, steps_needed=5)
    commands = []
    result = run_policy(robot, walk, lambda t: commands.append(t) or np.zeros(3), seconds=1.6, recovery=get_up)
    assert (result.falls, result.recoveries, result.fell, result.completed) == (2, 2, False, True)
    assert result.fall_time is None and result.stopped_by is None
    assert walk.resets == 3 and get_up.resets == 2  # the start and after each recovery; each fall
    assert walk.steps + get_up.steps == 80 and get_up.steps == 10
    assert commands == pytest.approx([k * DT for k in range(80)])  # the schedule went on through the recoveries


def test_a_recovery_that_gives_up_ends_the_run_as_a_fall(description):
    script = [(UPRIGHT, STILL)] * 10 + [(LYING, STILL)] * 100
    robot = ScriptedRobot(description, script)
    result = run_policy(robot, HoldHome(robot), seconds=2.0, recovery=Recovery(robot, steps_needed=20,
                                                                                succeeds=False))
    assert (result.falls, result.recoveries, result.fell, result.stopped_by) == (1, 0, True, "fall")
    assert result.fall_time == pytest.approx(11 * DT)  # the 11th step read the first tilted IMU
    assert len(robot.sent) == 11 + 20


def test_without_a_recovery_a_fall_still_stops_the_run(description):
    robot = ScriptedRobot(description, [(UPRIGHT, STILL)] * 4 + [(LYING, STILL)] * 10)
    result = run_policy(robot, HoldHome(robot), seconds=1.0)
    assert (result.falls, result.fell, result.stopped_by, len(robot.sent)) == (1, True, "fall", 5)


@pytest.mark.slow
def test_sim_run_with_on_fall_get_up_stands_up_after_a_kick_and_walks_on():
    """`sim run --on-fall get-up` as a library call: walk-rl kicked forwards with 1.5 m/s falls on its front, the
    get-up policy stands it up and walk-rl walks on, upright, to the end of the run."""
    from toddlerbot.runtime.robustness import DirectedKick
    from toddlerbot.sessions.sim import sim_session

    session = sim_session("walk-rl", "0:0.05,0,0", seconds=16.0, on_fall="get-up")
    result = session.run(DirectedKick(session.robot, 1.5, 0.0, 2.0))
    assert (result.falls, result.recoveries, result.fell) == (1, 1, False), session.recovery.status.describe()
    log = result.log
    recovering = log.recovering.astype(bool)
    walking_on = log.time > log.time[recovering].max()
    assert 2.0 < recovering.sum() * log.control_dt < 12.0
    assert walking_on.sum() * log.control_dt > 3.0
    standing = session.robot.standing_height
    assert log.base_pos[walking_on, 2].min() > 0.9 * standing  # walking at its height again
