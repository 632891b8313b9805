"""Reference tables: the command grid, snapping, and tabulating a walking generator."""

from types import SimpleNamespace

import numpy as np
import pytest

from toddlerbot.rl.config import CommandConfig
from toddlerbot.rl.reference import CommandGrid, leg_motor_indices, standing_table, zmp_table
from toddlerbot.robot.description import RobotDescription


def test_grid_contains_zero_and_snaps_to_nearest_point():
    grid = CommandGrid.from_config(CommandConfig(vx=(-0.1, 0.2), vy=(-0.1, 0.1), yaw=(-0.4, 0.4), grid=(4, 3, 5)))
    assert 0.0 in grid.vx and 0.0 in grid.vy and 0.0 in grid.yaw
    index = grid.snap(np.array([[0.19, -0.02, 0.21], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(grid.command(index), [[0.2, 0.0, 0.2], [0.0, 0.0, 0.0]], atol=1e-12)


def test_grid_snap_agrees_between_numpy_and_jax():
    jnp = pytest.importorskip("jax.numpy")
    grid = CommandGrid.from_config(CommandConfig())
    cmds = np.random.default_rng(0).uniform(-0.5, 0.5, (50, 3))
    np.testing.assert_array_equal(grid.snap(cmds), np.asarray(grid.snap(jnp.asarray(cmds), jnp)))


class FakeWalk:
    """A 'generator' whose leg joints and contacts are simple known functions of command and time."""

    def __init__(self, description, period):
        self.tmap = description.transmission
        self.period = period
        self.home = np.array(description.home_joint_pos)

    def reference(self, command, t):
        q = self.home.copy()
        q[self.tmap.joint_names.index("left_hip_pitch")] += command[0] * np.sin(2 * np.pi * t / self.period)
        q[self.tmap.joint_names.index("left_knee")] += 0.1 * command[2]
        left_down = (t / self.period) % 1.0 < 0.5
        return SimpleNamespace(joint_pos=q, contact=np.array([left_down, not left_down]))


def test_zmp_table_tabulates_steady_state_cycle_in_motor_space():
    description = RobotDescription.load()
    cfg = CommandConfig(grid=(3, 3, 3))
    table = zmp_table(description, FakeWalk(description, 0.72), cfg, period=0.72, start_time=0.4, n_phase=8)
    legs = leg_motor_indices(description)
    names = list(description.motor_names)
    assert table.leg_motor_pos.shape == (3, 3, 3, 8, 12)
    i = (2, 1, 1)  # vx = max, vy = 0, yaw = 0
    hip = list(legs).index(names.index("left_hip_pitch"))
    vx = table.grid.vx[2]
    phase = 0.4 / 0.72 + np.arange(8) / 8  # the table starts at start_time + 2 cycles
    np.testing.assert_allclose(table.leg_motor_pos[i][:, hip] - description.home_motor_pos[legs][hip],
                               vx * np.sin(2 * np.pi * phase), atol=1e-9)
    # the knee is driven through a transmission: the motor value differs from the joint offset but is not home
    assert not np.allclose(table.leg_motor_pos[2, 1, 2, 0], table.leg_motor_pos[2, 1, 1, 0])
    assert table.contact[i][:, 0].sum() + table.contact[i][:, 1].sum() == 8
    assert table.phase_index(0.72 * 1.5) == 4
    zero = tuple(table.grid.snap(np.zeros(3)))  # standing still: home pose, both feet down
    np.testing.assert_allclose(table.leg_motor_pos[zero], np.tile(description.home_motor_pos[legs], (8, 1)))
    assert table.contact[zero].min() == 1.0


def test_standing_table_is_home_with_both_feet_down():
    description = RobotDescription.load()
    table = standing_table(description, CommandConfig(grid=(3, 3, 3)), period=0.72, n_phase=4)
    legs = leg_motor_indices(description)
    np.testing.assert_allclose(table.leg_motor_pos[1, 2, 0, 3], description.home_motor_pos[legs])
    assert table.contact.min() == 1.0
