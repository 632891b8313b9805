"""The gait reference: tabulating a walking generator, interpolating between grid points (numpy = JAX), and the
tabulated ZMP gait being in phase with walk-zmp started the way DAgger starts it."""

from types import SimpleNamespace

import numpy as np
import pytest

from toddlerbot.policies.rl_inference import GaitReference, leg_gain_scale
from toddlerbot.rl.config import CommandConfig
from toddlerbot.rl.reference import grid_axes, leg_motor_indices, standing_table, zmp_table
from toddlerbot.robot.description import RobotDescription


@pytest.fixture(scope="module")
def description():
    return RobotDescription.load()


def test_grid_axes_contain_zero():
    vx, vy, yaw = grid_axes(CommandConfig(vx=(-0.1, 0.2), vy=(-0.1, 0.1), yaw=(-0.4, 0.4), grid=(4, 3, 5)))
    assert 0.0 in vx and 0.0 in vy and 0.0 in yaw
    np.testing.assert_allclose(yaw, [-0.4, -0.2, 0.0, 0.2, 0.4])


class FakeWalk:
    """A 'generator' whose leg joints and contacts are known functions of the command schedule and the tick."""

    def __init__(self, description, dt):
        self.tmap = description.transmission
        self.home = np.array(description.home_joint_pos)
        self.dt = dt

    def trajectory(self, commands, duration):
        hip, knee = self.tmap.joint_names.index("left_hip_pitch"), self.tmap.joint_names.index("left_knee")
        joints, contact = [], []
        for tick in range(round(duration / self.dt)):
            command = commands(tick * self.dt)
            q = self.home.copy()
            q[hip] += command[0] * np.sin(2 * np.pi * tick / 8)
            q[knee] += 0.1 * command[2]
            joints.append(q)
            contact.append([tick % 8 < 4, tick % 8 >= 4])
        return SimpleNamespace(joint_pos=np.array(joints), contact=np.array(contact))


def test_zmp_table_keeps_the_last_cycle_in_motor_space(description):
    cfg = CommandConfig(grid=(3, 3, 3))
    table = zmp_table(description, FakeWalk(description, 0.02), cfg, period=0.16, dt=0.02, warmup_cycles=2)
    legs = leg_motor_indices(description)
    names = list(description.motor_names)
    assert table.leg_motor_pos.shape == (3, 3, 3, 8, 12)
    hip = list(legs).index(names.index("left_hip_pitch"))
    vx = table.vx[2]
    np.testing.assert_allclose(table.leg_motor_pos[2, 1, 1][:, hip] - description.home_motor_pos[legs][hip],
                               vx * np.sin(2 * np.pi * np.arange(8) / 8), atol=1e-9)  # bin p = tick p of a cycle
    # the knee is driven through a transmission: the motor value differs from the joint offset but is not home
    assert not np.allclose(table.leg_motor_pos[2, 1, 2, 0], table.leg_motor_pos[2, 1, 1, 0])
    np.testing.assert_array_equal(table.contact[0, 0, 0, :, 0], [1, 1, 1, 1, 0, 0, 0, 0])


def _random_table(seed=0):
    rng = np.random.default_rng(seed)
    return GaitReference(np.array([-0.1, 0.0, 0.1, 0.15]), np.array([-0.08, 0.0, 0.08]), np.array([-0.4, 0.0, 0.4]),
                         0.6, rng.normal(size=(4, 3, 3, 30, 12)), rng.integers(0, 2, (4, 3, 3, 30, 2)).astype(float))


def test_interpolated_reference_equals_the_table_at_grid_points_and_phase_bins():
    table = _random_table()
    for (i, j, k, p) in [(0, 0, 0, 0), (3, 2, 2, 29), (1, 1, 1, 7), (2, 0, 1, 15)]:
        command = np.array([table.vx[i], table.vy[j], table.yaw[k]])
        leg, contact = table.at(command, p * 0.02 + 3 * 0.6)  # three cycles later: the same phase
        np.testing.assert_allclose(leg, table.leg_motor_pos[i, j, k, p], atol=1e-9)
        np.testing.assert_allclose(contact, table.contact[i, j, k, p], atol=1e-9)


def test_interpolation_is_multilinear_and_clamped_to_the_grid():
    table = _random_table()
    L = table.leg_motor_pos
    # halfway between two vx points, a quarter of the way between phase bins 29 and 0 (periodic)
    leg, _ = table.at(np.array([0.05, 0.0, 0.0]), 29.25 * 0.02)
    expected = 0.75 * (L[1, 1, 1, 29] + L[2, 1, 1, 29]) / 2 + 0.25 * (L[1, 1, 1, 0] + L[2, 1, 1, 0]) / 2
    np.testing.assert_allclose(leg, expected, atol=1e-9)
    # a command beyond the reach is the edge of the table
    np.testing.assert_allclose(table.at(np.array([0.3, -0.2, 1.0]), 0.0)[0], L[3, 0, 2, 0], atol=1e-9)


def test_interpolation_agrees_between_numpy_and_jax():
    jnp = pytest.importorskip("jax.numpy")
    table = _random_table()
    rng = np.random.default_rng(1)
    for _ in range(20):
        command, t = rng.uniform([-0.15, -0.1, -0.5], [0.2, 0.1, 0.5]), rng.uniform(0, 5)
        leg, contact = table.at(command, t)
        leg_j, contact_j = table.at(jnp.asarray(command, jnp.float32), jnp.asarray(t, jnp.float32), jnp)
        # float32 time: t mod period is off by ~1e-6 s, the phase by ~5e-5 bins of a table that jumps by ~1 per bin
        np.testing.assert_allclose(np.asarray(leg_j), leg, atol=2e-4)
        np.testing.assert_allclose(np.asarray(contact_j), contact, atol=2e-4)


def test_standing_table_is_home_with_both_feet_down(description):
    table = standing_table(description, CommandConfig(grid=(3, 3, 3)), period=0.6, n_phase=4)
    legs = leg_motor_indices(description)
    np.testing.assert_allclose(table.leg_motor_pos[1, 2, 0, 3], description.home_motor_pos[legs])
    assert table.contact.min() == 1.0


def test_leg_gains_follow_the_swinging_leg():
    stance = np.full(4, 2.0)
    swing = np.array([[3.0, 3.0, 0, 0], [0, 0, 3.0, 3.0]])
    np.testing.assert_array_equal(leg_gain_scale(np.array([1.0, 1.0]), stance, swing), [2, 2, 2, 2])
    np.testing.assert_array_equal(leg_gain_scale(np.array([0.0, 1.0]), stance, swing), [3, 3, 2, 2])
    np.testing.assert_array_equal(leg_gain_scale(np.array([1.0, 0.2]), stance, swing), [2, 2, 3, 3])
