"""Reward terms of the motion-tracking environment (DeepMimic-style), one named function each (JAX), and its table
of them with their weights (`TRACK_REWARDS`).

The tracking terms are kernels exp(-sigma * error^2) of the robot against the reference row it should have reached:
1 when it tracks exactly, falling towards 0 with the error; the action-rate term is a penalty (<= 0, 0 for a steady
action) and survival is 1 while the episode goes on. Each kernel's sharpness is a named constant below (the table in
docs/rl.md, "Motion tracking"). The environment adds ``weight * term`` times the control period, as walking does
(`rewards.RewardTerms`).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from toddlerbot.rl import rewards
from toddlerbot.rl.config import RewardConfig

MOTOR_POS_SIGMA = 2.0
"""1/rad^2: 0.1 rad off on each of the 30 motors: 0.55."""
MOTOR_VEL_SIGMA = 0.05
"""1/(rad/s)^2: 0.5 rad/s off on each of the 30 motors: 0.69."""
ORIENTATION_SIGMA = 50.0
"""Of 1 - <q, q_ref>^2 (sin^2 of half the angle between them): 0.2 rad off: 0.61."""
HEIGHT_SIGMA = 400.0
"""1/m^2: 5 cm off: 0.37."""
END_EFFECTOR_SIGMA = 40.0
"""1/m^2 of the summed squared distances of the four end effectors: 5 cm off each: 0.67."""


class TrackQuantities(NamedTuple):
    """What the tracking terms read, for one environment after one control step, beside the reference row."""

    motor_pos: jax.Array
    """(n_motors,) rad."""
    ref_motor_pos: jax.Array
    motor_vel: jax.Array
    """(n_motors,) rad/s."""
    ref_motor_vel: jax.Array
    torso_quat: jax.Array
    """(4,) w, x, y, z in the world frame."""
    ref_torso_quat: jax.Array
    torso_height: jax.Array
    """m."""
    ref_torso_height: jax.Array
    end_effectors: jax.Array
    """(4, 3) feet and hands in the torso frame, m (`motion_reference.MotionReference.end_effectors`)."""
    ref_end_effectors: jax.Array
    action: jax.Array
    last_action: jax.Array
    alive: jax.Array
    """1.0 unless the episode ended in this step."""


def motor_pos(q: TrackQuantities, c: RewardConfig) -> jax.Array:
    return jnp.exp(-MOTOR_POS_SIGMA * jnp.sum((q.motor_pos - q.ref_motor_pos) ** 2))


def motor_vel(q: TrackQuantities, c: RewardConfig) -> jax.Array:
    return jnp.exp(-MOTOR_VEL_SIGMA * jnp.sum((q.motor_vel - q.ref_motor_vel) ** 2))


def torso_orientation(q: TrackQuantities, c: RewardConfig) -> jax.Array:
    return jnp.exp(-ORIENTATION_SIGMA * (1.0 - jnp.dot(q.torso_quat, q.ref_torso_quat) ** 2))


def torso_height(q: TrackQuantities, c: RewardConfig) -> jax.Array:
    return jnp.exp(-HEIGHT_SIGMA * (q.torso_height - q.ref_torso_height) ** 2)


def end_effectors(q: TrackQuantities, c: RewardConfig) -> jax.Array:
    return jnp.exp(-END_EFFECTOR_SIGMA * jnp.sum((q.end_effectors - q.ref_end_effectors) ** 2))


def action_rate(q: TrackQuantities, c: RewardConfig) -> jax.Array:
    """Change of the residual action (every motor's) since the last step."""
    return -jnp.sum((q.action - q.last_action) ** 2)


TRACK_REWARDS = rewards.RewardTerms(
    (motor_pos, 5.0), (motor_vel, 1.0), (torso_orientation, 2.0), (torso_height, 1.0), (end_effectors, 2.0),
    (action_rate, 0.1), (rewards.survival, 5.0),
)
"""The tracking environment's terms with their weights (DeepMimic's proportions: pose first, then end effectors,
orientation and velocities)."""
