"""Reward terms of appendix Table 6, one named function each (JAX), and the walking environment's table of them
with their weights (`WALK_REWARDS`).

Every term reads the `StepQuantities` computed once per control step and returns a scalar. Imitation and
survival terms are rewards in [0, 1]; regularisation terms are penalties (<= 0) except feet air time and
clearance, which may be either sign. An environment adds ``weight * term`` over its `RewardTerms` (its weights:
`RewardConfig.weights`, by default the table's) and multiplies the sum by the control period, so a reward rate
does not depend on the control frequency.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from toddlerbot.rl.config import RewardConfig


class StepQuantities(NamedTuple):
    """Everything a reward term may read, for one environment after one control step."""

    torso_quat: jax.Array
    """(4,) w, x, y, z in the world frame."""
    ref_torso_quat: jax.Array
    """(4,) upright with the commanded (integrated) yaw."""
    lin_vel: jax.Array
    """(3,) torso linear velocity in the yaw-aligned frame, m/s."""
    ang_vel: jax.Array
    """(3,) torso angular velocity in the torso frame, rad/s."""
    avg_vel: jax.Array
    """(3,) vx, vy (yaw frame, m/s) and yaw rate (rad/s) of the torso, exponentially averaged over
    `RewardConfig.velocity_average_s`: the walking velocity without the in-cycle sway."""
    path_error: jax.Array
    """(2,) x, y (yaw frame, m) of the torso from the path the commands lead along, forgotten with the time
    constant `RewardConfig.path_memory_s`: a walking-speed bias accumulates here (what `eval tracking` measures
    as the position error), a push's displacement too."""
    command: jax.Array
    """(3,) vx, vy m/s, yaw rate rad/s."""
    leg_pos: jax.Array
    """(12,) leg motor angles, rad."""
    ref_leg_pos: jax.Array
    home_leg_pos: jax.Array
    contact: jax.Array
    """(2,) left/right foot touching the floor, 0/1."""
    ref_contact: jax.Array
    first_contact: jax.Array
    """(2,) foot touched down in this step."""
    air_time: jax.Array
    """(2,) s in the air before this step's touchdown."""
    feet_height: jax.Array
    """(2,) sole-centre height above the floor, m."""
    feet_vel_xy: jax.Array
    """(2, 2) horizontal foot velocity, m/s."""
    feet_up_z: jax.Array
    """(2,) world-z component of each foot's up axis (1 = flat)."""
    feet_lateral_distance: jax.Array
    """Distance between the feet along the torso's lateral axis, m."""
    roll: jax.Array
    pitch: jax.Array
    self_collision: jax.Array
    """Number of penetrating robot-robot contacts."""
    action: jax.Array
    last_action: jax.Array
    last_last_action: jax.Array
    motor_torque: jax.Array
    """(n_motors,) N*m."""
    motor_vel: jax.Array
    """(n_motors,) rad/s."""
    alive: jax.Array
    """1.0 unless the robot fell in this step."""


Term = Callable[[StepQuantities, RewardConfig], jax.Array]


def _kernel(err2: jax.Array, sigma: float) -> jax.Array:
    return jnp.exp(-sigma * err2)


def torso_quat(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """Orientation tracking: exp(-sigma * (1 - <q, q_ref>^2))."""
    return _kernel(1.0 - jnp.dot(q.torso_quat, q.ref_torso_quat) ** 2, c.tracking_sigma)


def lin_vel_xy(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return _kernel(jnp.sum((q.avg_vel[:2] - q.command[:2]) ** 2), c.velocity_sigma)


def path_xy(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """Position tracking: stay on the commanded path (not in Table 6; off unless weighted)."""
    return _kernel(jnp.sum(q.path_error**2), c.path_sigma)


def lin_vel_z(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return _kernel(q.lin_vel[2] ** 2, c.tracking_sigma)


def ang_vel_xy(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return _kernel(jnp.sum(q.ang_vel[:2] ** 2), c.tracking_sigma / 4)


def ang_vel_z(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return _kernel((q.avg_vel[2] - q.command[2]) ** 2, c.velocity_sigma / 4)


def leg_motor_pos(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return _kernel(jnp.sum((q.leg_pos - q.ref_leg_pos) ** 2), c.leg_pos_sigma)


def feet_contact(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """Fraction of feet whose contact state matches the reference stance."""
    return jnp.mean(q.contact == q.ref_contact)


def _moving(q: StepQuantities) -> jax.Array:
    return (jnp.linalg.norm(q.command) > 1e-3).astype(jnp.float32)


def feet_air_time(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """Touchdowns after a swing longer than the target are rewarded, shorter ones penalised (only when moving)."""
    return jnp.sum((q.air_time - c.air_time_target) * q.first_contact) * _moving(q)


def feet_clearance(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """Swing feet (reference says not in stance) should be at the clearance target; penalty in m^2 x 1e3."""
    swing = 1.0 - q.ref_contact
    return -1e3 * jnp.sum(swing * (q.feet_height - c.clearance_target) ** 2) * _moving(q)


def feet_distance(q: StepQuantities, c: RewardConfig) -> jax.Array:
    lo, hi = c.feet_distance_range
    d = q.feet_lateral_distance
    return -(jnp.clip(lo - d, 0.0) + jnp.clip(d - hi, 0.0)) / lo


def feet_slip(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return -jnp.sum(q.contact * jnp.sum(q.feet_vel_xy**2, axis=-1)) * 100.0


def align_ground(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """Feet in contact should lie flat: penalise the tilt of their up axis."""
    return -jnp.sum(q.contact * (1.0 - q.feet_up_z))


def stand_still(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """With a zero command, stay at the home pose."""
    return -jnp.sum(jnp.abs(q.leg_pos - q.home_leg_pos)) * (1.0 - _moving(q))


def torso_roll(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return -jnp.clip(jnp.abs(q.roll) - c.torso_tilt_limit, 0.0) / c.torso_tilt_limit


def torso_pitch(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return -jnp.clip(jnp.abs(q.pitch) - c.torso_tilt_limit, 0.0) / c.torso_tilt_limit


def collision(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return -q.self_collision


def leg_action_rate(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return -jnp.sum((q.action - q.last_action) ** 2)


def leg_action_acc(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return -jnp.sum((q.action - 2 * q.last_action + q.last_last_action) ** 2)


def motor_torque(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return -jnp.sum(q.motor_torque**2)


def energy(q: StepQuantities, c: RewardConfig) -> jax.Array:
    """Mechanical power, W."""
    return -jnp.sum(jnp.abs(q.motor_torque * q.motor_vel))


def survival(q: StepQuantities, c: RewardConfig) -> jax.Array:
    return q.alive


class RewardTerms:
    """An environment's reward terms, each beside its default weight, in summation order (a reordering changes the
    sum's rounding, so a seeded run's results)."""

    def __init__(self, *weighted: tuple[Term, float]) -> None:
        self.terms: dict[str, Term] = {term.__name__: term for term, _ in weighted}
        self.default_weights: dict[str, float] = {term.__name__: float(weight) for term, weight in weighted}
        if len(self.terms) != len(weighted):
            raise ValueError("reward terms: a term is listed twice")

    def __iter__(self):
        return iter(self.terms)

    def weights(self, given: dict[str, float] | None) -> dict[str, float]:
        """The weights a configuration means: the defaults for None, else `given`, which must weight every term
        and no other (one line naming the missing and unknown ones)."""
        if given is None:
            return dict(self.default_weights)
        missing, extra = set(self.terms) - set(given), set(given) - set(self.terms)
        if missing or extra:
            raise ValueError(f"reward weights: missing {sorted(missing)}, unknown {sorted(extra)}")
        return {name: float(given[name]) for name in self.terms}

    def saved_weights(self, saved: dict[str, float]) -> dict[str, float]:
        """A saved run's weights; a term added since the run was saved has weight 0 (the run trained without it)."""
        return self.weights({**dict.fromkeys(self.terms, 0.0), **saved})

    def total(self, q: StepQuantities, cfg: RewardConfig, dt: float) -> tuple[jax.Array, dict[str, jax.Array]]:
        """(total reward of the step, unweighted value of each term) with ``cfg``'s weights, which the environment
        has resolved (`weights`)."""
        terms = {name: fn(q, cfg) for name, fn in self.terms.items()}
        total = sum(cfg.weights[name] * value for name, value in terms.items()) * dt
        return total, terms


WALK_REWARDS = RewardTerms(
    # imitation
    (torso_quat, 1.0), (lin_vel_xy, 5.0),
    (path_xy, 0.0),  # not in Table 6: off unless `rl train --reward-weight path_xy=W`
    (lin_vel_z, 1.0), (ang_vel_xy, 2.0), (ang_vel_z, 5.0), (leg_motor_pos, 5.0), (feet_contact, 1.0),
    # regularisation
    (feet_air_time, 500.0), (feet_clearance, 0.05), (feet_distance, 1.0), (feet_slip, 0.05), (align_ground, 1.0),
    (stand_still, 1.0), (torso_roll, 0.5), (torso_pitch, 0.5), (collision, 0.1), (leg_action_rate, 0.05),
    (leg_action_acc, 0.05), (motor_torque, 0.01), (energy, 0.05),
    # survival
    (survival, 10.0),
)
"""The walking environment's terms with their Table 6 weights."""
