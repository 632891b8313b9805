"""Per-episode domain randomisation (JAX): one independent draw per environment at every reset.

The draw is a `DRParams` pytree kept in the environment state; `model_fields` turns it into that env's model
parameters (floor friction, joint damping/armature/friction loss, link masses), which either physics backend
applies, and `apply_to_actuators` into its actuator parameters (kp/kd, torque and speed limits). Under
``jax.vmap`` every env thus simulates its own robot.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from toddlerbot.actuation.model import ActuatorArrays
from toddlerbot.rl.config import RandomizationConfig
from toddlerbot.robot import upper_body


class DRParams(NamedTuple):
    floor_friction: jax.Array
    """Sliding friction coefficient of the floor."""
    damping_scale: jax.Array
    """(nv,) multipliers."""
    armature_scale: jax.Array
    frictionloss_scale: jax.Array
    mass_scale: jax.Array
    """(nbody,) multipliers of mass and inertia."""
    torso_added_mass: jax.Array
    """kg."""
    kp_scale: jax.Array
    """(n_motors,) multipliers."""
    kd_scale: jax.Array
    tau_max_scale: jax.Array
    q_dot_max_scale: jax.Array
    obs_noise_level: jax.Array
    action_delay: jax.Array
    """1.0: actions take effect one control step late."""
    imu_age: jax.Array
    """s; age of the IMU reading the actor sees."""


def nominal(nv: int, nbody: int, n_motors: int) -> DRParams:
    """The un-randomised robot (all scales 1, friction 1, no delay)."""
    one = jnp.ones(())
    return DRParams(one, jnp.ones(nv), jnp.ones(nv), jnp.ones(nv), jnp.ones(nbody), jnp.zeros(()),
                    jnp.ones(n_motors), jnp.ones(n_motors), jnp.ones(n_motors), jnp.ones(n_motors), one,
                    jnp.zeros(()), jnp.zeros(()))


def sample(key: jax.Array, cfg: RandomizationConfig, nv: int, nbody: int, n_motors: int) -> DRParams:
    keys = iter(jax.random.split(key, 13))

    def u(rng: tuple[float, float], shape: tuple[int, ...] = ()) -> jax.Array:
        return jax.random.uniform(next(keys), shape, minval=rng[0], maxval=rng[1])

    return DRParams(
        floor_friction=u(cfg.floor_friction),
        damping_scale=u(cfg.damping_scale, (nv,)),
        armature_scale=u(cfg.armature_scale, (nv,)),
        frictionloss_scale=u(cfg.frictionloss_scale, (nv,)),
        mass_scale=u(cfg.mass_scale, (nbody,)),
        torso_added_mass=u(cfg.torso_added_mass),
        kp_scale=u(cfg.kp_scale, (n_motors,)),
        kd_scale=u(cfg.kd_scale, (n_motors,)),
        tau_max_scale=u(cfg.tau_max_scale, (n_motors,)),
        q_dot_max_scale=u(cfg.q_dot_max_scale, (n_motors,)),
        obs_noise_level=u(cfg.obs_noise_level),
        action_delay=(jax.random.uniform(next(keys)) < cfg.action_delay_prob).astype(jnp.float32),
        # a key of its own, so that the draws above stay those of runs from before the IMU age existed
        imu_age=jax.random.uniform(jax.random.fold_in(key, 13), minval=cfg.imu_age_s[0], maxval=cfg.imu_age_s[1]),
    )


def upper_body_offsets(key: jax.Array, fraction: float, home: jax.Array, motor_range: jax.Array,
                       upper_body_mask: jax.Array) -> jax.Array:
    """(n_motors,) offsets from home of an upper-body pose: each motor flagged in ``upper_body_mask`` drawn
    uniformly between home and ``fraction`` of the way to its lower or upper limit
    (`toddlerbot.robot.upper_body.upper_body_offsets`)."""
    u = jax.random.uniform(key, home.shape, minval=-1.0, maxval=1.0)
    return upper_body.upper_body_offsets(u, fraction, home, motor_range, upper_body_mask, xp=jnp)


def hand_force(key: jax.Array, largest: float) -> jax.Array:
    """(3,) a pull on each hand in the robot's heading frame, N: horizontal part of random direction and length
    up to ``largest``, vertical part within half of it either way (`RandomizationConfig.hand_force`)."""
    k_dir, k_len, k_up = jax.random.split(key, 3)
    angle = jax.random.uniform(k_dir, maxval=2 * jnp.pi)
    length = jax.random.uniform(k_len, maxval=largest)
    up = jax.random.uniform(k_up, minval=-0.5 * largest, maxval=0.5 * largest)
    return jnp.array([length * jnp.cos(angle), length * jnp.sin(angle), up])


def push_interval(key: jax.Array, cfg: RandomizationConfig) -> jax.Array:
    """s until the next push, uniform in `RandomizationConfig.push_interval_s`."""
    lo, hi = cfg.push_interval_s
    return jax.random.uniform(key, minval=lo, maxval=hi)


def push(key: jax.Array, timer: jax.Array, cfg: RandomizationConfig, enabled: bool,
         ctrl_dt: float) -> tuple[jax.Array, jax.Array]:
    """(horizontal velocity kick of the torso (2,) m/s, the push timer after this control step): when an env's
    timer has run out (and pushes are ``enabled``), a kick of random direction and a speed in the push band, and the
    next interval; otherwise no kick and the timer counts down."""
    k_dir, k_mag, k_next = jax.random.split(key, 3)
    due = (timer <= 0) & enabled
    angle = jax.random.uniform(k_dir, maxval=2 * jnp.pi)
    speed = jax.random.uniform(k_mag, minval=cfg.push_velocity_min, maxval=cfg.push_velocity)
    kick = jnp.where(due, speed, 0.0) * jnp.array([jnp.cos(angle), jnp.sin(angle)])
    return kick, jnp.where(due, push_interval(k_next, cfg), timer - ctrl_dt)


def model_fields(nominal: dict[str, jax.Array], p: DRParams, floor_geom: int, torso_body: int) -> dict[str, jax.Array]:
    """The env's own physical parameters (`toddlerbot.rl.physics.MODEL_FIELDS`): the nominal model's with this
    draw's floor friction, joint damping/armature/friction loss and link masses/inertias. Both physics backends
    take these arrays (MJX replaces them in its model, the CPU backend writes them into the env's MjModel)."""
    mass = nominal["body_mass"] * p.mass_scale
    added = jnp.zeros_like(mass).at[torso_body].set(p.torso_added_mass)
    scale = (mass + added) / jnp.maximum(nominal["body_mass"], 1e-9)
    return {
        "geom_friction": jnp.asarray(nominal["geom_friction"]).at[floor_geom, 0].set(p.floor_friction),
        "dof_damping": nominal["dof_damping"] * p.damping_scale,
        "dof_armature": nominal["dof_armature"] * p.armature_scale,
        "dof_frictionloss": nominal["dof_frictionloss"] * p.frictionloss_scale,
        "body_mass": mass + added,
        "body_inertia": nominal["body_inertia"] * scale[:, None],
    }


def apply_to_actuators(a: ActuatorArrays, p: DRParams) -> ActuatorArrays:
    """Scaled gains and limits; the speed breakpoints scale together so their order is kept."""
    return a._replace(
        kp=a.kp * p.kp_scale, kd=a.kd * p.kd_scale, tau_max=a.tau_max * p.tau_max_scale,
        tau_q_dot_max=a.tau_q_dot_max * p.tau_max_scale, q_dot_tau_max=a.q_dot_tau_max * p.q_dot_max_scale,
        q_dot_max=a.q_dot_max * p.q_dot_max_scale,
    )
