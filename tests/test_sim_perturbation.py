"""Seeded perturbations of the simulated robot: each change lands in the model, kicks are exact, seeds repeat."""

import dataclasses
import logging
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from toddlerbot.locomotion.config import WALK_REACH, CommandReach
from toddlerbot.policies.walk_zmp import WalkZMPPolicy
from toddlerbot.runtime.robustness import DirectedKick, KickSchedule, directed_kick_trial, kick_grid, reach_commands
from toddlerbot.runtime.runner import run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.perturbation import Perturbation, perturbed_robot


def test_sampled_perturbations_stay_in_their_ranges_and_repeat_per_seed(description):
    a, b = Perturbation.sample(3, description), Perturbation.sample(3, description)
    assert a == b and a != Perturbation.sample(4, description)
    assert len(a.joint_offset) == description.n_motors and max(map(abs, a.joint_offset)) <= 0.01
    assert 0.9 <= a.torso_mass_scale <= 1.1 and 0.5 <= a.friction <= 1.0
    models = {m.model for m in description.motors}
    appendix = ("damping", "armature", "frictionloss", "tau_max", "q_dot_max", "kd_min", "tau_brake")  # `perturbed`
    assert {(m, p) for m, p, _ in a.motor_scale} == {(m, p) for m in models for p in appendix}
    assert all(0.9 <= f <= 1.1 for _, _, f in a.motor_scale)


def test_perturbed_robot_carries_mass_friction_motor_parameters_and_joint_offsets(description):
    p = Perturbation.sample(1, description)
    robot = perturbed_robot(description, p)
    nominal = description.model("floating", scene=True)
    torso = nominal.body(description.handles.torso).id
    assert robot.model.body_mass[torso] == pytest.approx(nominal.body_mass[torso] * p.torso_mass_scale)
    assert np.all(robot.model.geom_friction[:, 0] == p.friction)
    assert nominal.geom_friction[0, 0] == 1.0  # the shared compiled model is untouched
    model, param, factor = p.motor_scale[0]
    nominal_value = getattr(description.catalogue[model].actuator, param)
    assert getattr(robot.description.catalogue[model].actuator, param) == pytest.approx(nominal_value * factor)
    obs = robot.reset()
    np.testing.assert_allclose(obs.motor_pos - description.home_motor_pos, p.joint_offset, atol=2e-3)


def test_kicks_add_exactly_the_speed_at_the_kick_times(description):
    robot = MuJoCoRobot(description)
    kicks = KickSchedule(robot, Perturbation(seed=5, kick_speed=0.3))
    robot.reset()
    for t in np.arange(0.0, 7.0, 0.02):
        before = robot.base_lin_vel[:2]
        kicks.kick_at(dataclasses.replace(robot.observe(), time=float(t)))
        if kicks.kicks and kicks.kicks[-1][0] == pytest.approx(t):
            assert np.linalg.norm(robot.base_lin_vel[:2] - before) == pytest.approx(0.3)
    assert [k[0] for k in kicks.kicks] == pytest.approx([2.0, 4.5])
    assert all(np.hypot(dx, dy) == pytest.approx(0.3) for _, dx, dy in kicks.kicks)


def test_a_directed_kick_is_taken_in_the_heading_frame_once_at_its_time(description):
    robot = MuJoCoRobot(description)
    robot.reset()
    yaw = np.pi / 2  # the robot faces +y: a kick to its left pushes it towards -x
    robot.data.qpos[3:7] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    mujoco.mj_forward(robot.model, robot.data)
    kick = DirectedKick(robot, 0.3, np.pi / 2, 2.0)
    at = lambda t: SimpleNamespace(next_obs=SimpleNamespace(time=t))  # noqa: E731
    before = robot.base_lin_vel[:2]
    kick.on_step(at(1.98))
    np.testing.assert_array_equal(robot.base_lin_vel[:2], before)
    kick.on_step(at(2.0))
    kick.on_step(at(2.02))
    np.testing.assert_allclose(robot.base_lin_vel[:2] - before, [-0.3, 0.0], atol=1e-9)


def test_the_kick_grid_covers_every_direction_at_every_moment_of_a_gait_cycle():
    cells = kick_grid(directions=8, phases=6, period=0.6, start=2.0)
    assert len(cells) == 48 and len({(i, j) for i, j, _, _ in cells}) == 48
    assert sorted({round(np.degrees(d)) for _, _, d, _ in cells}) == list(range(0, 360, 45))
    assert sorted({round(t, 6) for _, _, _, t in cells}) == pytest.approx([2.0, 2.1, 2.2, 2.3, 2.4, 2.5])


def test_walk_zmp_standing_takes_a_small_kick_and_falls_to_a_large_one(description):
    make = WalkZMPPolicy
    assert directed_kick_trial(description, make, (0.0, 0.0, 0.0), 0.1, 0.0, 2.0, after=2.0) is None
    fall = directed_kick_trial(description, make, (0.0, 0.0, 0.0), 0.8, np.pi / 2, 2.0, after=2.0)
    assert fall is not None and 2.0 < fall < 4.0


def test_reach_commands_span_each_axis_both_ways_and_standing():
    commands = np.array(reach_commands(WALK_REACH))
    assert len(commands) == 10 and (commands == 0).all(axis=1).sum() == 1
    np.testing.assert_array_equal(commands.max(axis=0), WALK_REACH.high)
    np.testing.assert_array_equal(commands.min(axis=0), WALK_REACH.low)


def test_reach_must_straddle_zero():
    with pytest.raises(ValueError, match="vy: expected finite low <= 0 <= high"):
        CommandReach(low=(-0.1, 0.05, -0.4), high=(0.1, 0.08, 0.4))


def test_commands_beyond_the_reach_are_clamped_with_one_warning(caplog, description):
    robot = MuJoCoRobot(description)
    with caplog.at_level(logging.WARNING):
        result = run_policy(robot, WalkZMPPolicy(robot), lambda t: np.array([1e300, -5.0, 0.2]), 0.5)
    np.testing.assert_array_equal(result.log.command[-1], [0.15, -0.08, 0.2])
    warnings = [r.getMessage() for r in caplog.records if "beyond its reach" in r.getMessage()]
    assert len(warnings) == 1 and "clamped to (0.15, -0.08, 0.2)" in warnings[0]
