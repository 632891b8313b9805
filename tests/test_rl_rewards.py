"""Reward terms of Table 6: every term weighted once, and each term scores known situations as expected."""

import numpy as np
import pytest

jax = pytest.importorskip("jax")
jnp = jax.numpy

from toddlerbot.rl import rewards  # noqa: E402
from toddlerbot.rl.config import RewardConfig  # noqa: E402

TABLE_6 = {
    "torso_quat": 1.0, "lin_vel_xy": 5.0, "lin_vel_z": 1.0, "ang_vel_xy": 2.0, "ang_vel_z": 5.0, "leg_motor_pos": 5.0,
    "feet_contact": 1.0, "feet_air_time": 500.0, "feet_clearance": 0.05, "feet_distance": 1.0, "feet_slip": 0.05,
    "align_ground": 1.0, "stand_still": 1.0, "torso_roll": 0.5, "torso_pitch": 0.5, "collision": 0.1,
    "leg_action_rate": 0.05, "leg_action_acc": 0.05, "motor_torque": 0.01, "energy": 0.05, "survival": 10.0,
}


def quantities(**overrides):
    """A robot standing still, upright, tracking a zero command perfectly."""
    z2, z3, z12 = jnp.zeros(2), jnp.zeros(3), jnp.zeros(12)
    q = dict(
        torso_quat=jnp.array([1.0, 0, 0, 0]), ref_torso_quat=jnp.array([1.0, 0, 0, 0]), lin_vel=z3, ang_vel=z3,
        avg_vel=z3, path_error=z2, command=z3, leg_pos=z12, ref_leg_pos=z12, home_leg_pos=z12, contact=jnp.ones(2),
        ref_contact=jnp.ones(2),
        first_contact=z2, air_time=z2, feet_height=z2, feet_vel_xy=jnp.zeros((2, 2)), feet_up_z=jnp.ones(2),
        feet_lateral_distance=jnp.array(0.1), roll=jnp.array(0.0), pitch=jnp.array(0.0),
        self_collision=jnp.array(0.0), action=z12, last_action=z12, last_last_action=z12,
        motor_torque=jnp.zeros(30), motor_vel=jnp.zeros(30), alive=jnp.array(1.0),
    )
    q.update({k: jnp.asarray(v, dtype=jnp.float32) for k, v in overrides.items()})
    return rewards.StepQuantities(**q)


def test_weights_are_table_6_and_cover_every_term():
    walk = rewards.WALK_REWARDS
    assert walk.default_weights == {**TABLE_6, "path_xy": 0.0}  # the path term is ours, off by default
    assert set(walk) == set(TABLE_6) | {"path_xy"}
    assert walk.weights(None) == walk.default_weights  # a configuration without weights means the table's
    with pytest.raises(ValueError, match=r"missing \[.*'torso_quat'.*\], unknown \['toe'\]"):
        walk.weights({"survival": 1.0, "toe": 1.0})


def test_perfect_standing_earns_every_imitation_term_and_no_penalty():
    cfg = RewardConfig(weights=rewards.WALK_REWARDS.default_weights)
    total, terms = rewards.WALK_REWARDS.total(quantities(), cfg, dt=0.02)
    imitation = ("torso_quat", "lin_vel_xy", "lin_vel_z", "ang_vel_xy", "ang_vel_z", "leg_motor_pos", "feet_contact")
    for name in imitation:
        assert float(terms[name]) == pytest.approx(1.0)
    for name in set(TABLE_6) - set(imitation) - {"survival"}:
        assert float(terms[name]) == pytest.approx(0.0, abs=1e-7), name
    expected = (sum(TABLE_6[n] for n in imitation) + TABLE_6["survival"]) * 0.02
    assert float(total) == pytest.approx(expected, rel=1e-6)


def test_velocity_tracking_reads_the_averaged_velocity_not_the_sway():
    cfg = RewardConfig()
    q = quantities(command=[0.2, 0.0, 0.5], avg_vel=[0.1, 0.0, 0.5], lin_vel=[0.3, -0.1, 0.0], ang_vel=[0, 0, 1.5])
    assert float(rewards.lin_vel_xy(q, cfg)) == pytest.approx(np.exp(-cfg.velocity_sigma * 0.01), rel=1e-6)
    assert float(rewards.ang_vel_z(q, cfg)) == pytest.approx(1.0)
    # a 0.04 m/s bias of the walking speed costs 15 % of the term
    biased = quantities(command=[0.1, 0.0, 0.0], avg_vel=[0.06, 0.0, 0.0])
    assert float(rewards.lin_vel_xy(biased, cfg)) == pytest.approx(0.852, abs=1e-3)


def test_the_path_term_makes_a_small_speed_bias_cost_more_than_the_velocity_term_does():
    cfg = RewardConfig()
    assert float(rewards.path_xy(quantities(), cfg)) == 1.0
    # a 2 cm/s forward bias held for a while: the leaky path error settles at bias x memory = 4 cm
    bias = 0.02
    drift = quantities(path_error=[bias * cfg.path_memory_s, 0.0], avg_vel=[bias, 0.0, 0.0])
    assert float(rewards.path_xy(drift, cfg)) == pytest.approx(np.exp(-200 * 0.04**2), rel=1e-5)  # 0.726
    assert 1 - float(rewards.path_xy(drift, cfg)) > 6 * (1 - float(rewards.lin_vel_xy(drift, cfg)))  # 0.27 vs 0.04
    sideways = quantities(path_error=[0.0, -0.04])
    assert float(rewards.path_xy(sideways, cfg)) == pytest.approx(float(rewards.path_xy(drift, cfg)))


def test_penalties_grow_with_the_mistake():
    cfg = RewardConfig()
    assert float(rewards.leg_action_rate(quantities(action=np.full(12, 0.1)), cfg)) == pytest.approx(-0.12)
    assert float(rewards.leg_action_acc(quantities(action=np.full(12, 0.1), last_action=np.full(12, 0.2)), cfg)) \
        == pytest.approx(-12 * 0.3**2, rel=1e-5)
    assert float(rewards.energy(quantities(motor_torque=np.full(30, 2.0), motor_vel=np.full(30, -1.0)), cfg)) == -60
    assert float(rewards.torso_roll(quantities(roll=0.3), cfg)) == pytest.approx(-0.5)
    assert float(rewards.feet_distance(quantities(feet_lateral_distance=0.03), cfg)) == pytest.approx(-0.5)
    assert float(rewards.feet_slip(quantities(feet_vel_xy=[[0.1, 0.0], [0.0, 0.0]]), cfg)) == pytest.approx(-1.0)
    # stand still only applies with a zero command
    assert float(rewards.stand_still(quantities(leg_pos=np.full(12, 0.1)), cfg)) == pytest.approx(-1.2)
    assert float(rewards.stand_still(quantities(leg_pos=np.full(12, 0.1), command=[0.1, 0, 0]), cfg)) == 0.0


def test_air_time_rewards_long_steps_only_while_walking():
    cfg = RewardConfig()
    walking = dict(command=[0.1, 0, 0], first_contact=[1.0, 0.0])
    assert float(rewards.feet_air_time(quantities(air_time=[0.3, 0.0], **walking), cfg)) == pytest.approx(0.1)
    assert float(rewards.feet_air_time(quantities(air_time=[0.1, 0.0], **walking), cfg)) == pytest.approx(-0.1)
    assert float(rewards.feet_air_time(quantities(air_time=[0.3, 0.0], first_contact=[1.0, 0.0]), cfg)) == 0.0


def test_contact_mismatch_and_falling():
    cfg = RewardConfig()
    assert float(rewards.feet_contact(quantities(contact=[1.0, 0.0]), cfg)) == pytest.approx(0.5)
    assert float(rewards.survival(quantities(alive=0.0), cfg)) == 0.0
