"""Actor and critic observations of the walking environment (JAX).

The actor frame is `toddlerbot.policies.rl_inference.obs_frame` (the same function the robot runs, here with
``xp=jax.numpy``) computed from noisy sensor values; frames are stacked newest first. The critic sees the
actor observation plus privileged, noise-free state that the robot cannot measure.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from toddlerbot.policies.rl_inference import ObsConfig, gravity_in_frame, obs_frame


class Sensors(NamedTuple):
    """What the robot measures, in the units of `toddlerbot.robot.interface.Observation`."""

    motor_pos: jax.Array
    motor_vel: jax.Array
    gyro: jax.Array
    imu_quat: jax.Array


def add_noise(key: jax.Array, s: Sensors, cfg: ObsConfig, level: jax.Array) -> tuple[Sensors, jax.Array]:
    """Uniform sensor noise scaled by the env's noise level; returns the noisy sensors and the gravity vector
    (noise is added to the gravity direction rather than to the quaternion)."""
    k = jax.random.split(key, 4)

    def u(key: jax.Array, x: jax.Array, width: float) -> jax.Array:
        return x + level * width * jax.random.uniform(key, x.shape, minval=-1.0, maxval=1.0)

    noisy = s._replace(motor_pos=u(k[0], s.motor_pos, cfg.noise_motor_pos),
                       motor_vel=u(k[1], s.motor_vel, cfg.noise_motor_vel), gyro=u(k[2], s.gyro, cfg.noise_gyro))
    return noisy, u(k[3], gravity_in_frame(s.imu_quat, jnp), cfg.noise_gravity)


def aged_imu(previous: Sensors, now: Sensors, fraction: jax.Array) -> Sensors:
    """``now`` with its IMU reading (gyro, orientation) ``fraction`` of a control period old: interpolated towards
    the ``previous`` control step's (the orientation normalised, taken on ``now``'s side of the sphere)."""
    gyro = now.gyro + fraction * (previous.gyro - now.gyro)
    before = jnp.where(jnp.dot(previous.imu_quat, now.imu_quat) < 0, -previous.imu_quat, previous.imu_quat)
    quat = now.imu_quat + fraction * (before - now.imu_quat)
    return now._replace(gyro=gyro, imu_quat=quat / jnp.linalg.norm(quat))


def actor_frame(t: jax.Array, command: jax.Array, s: Sensors, gravity: jax.Array, home_motor_pos: jax.Array,
                last_action: jax.Array, cfg: ObsConfig) -> jax.Array:
    return obs_frame(t, command, s.motor_pos, home_motor_pos, s.motor_vel, last_action, s.gyro, gravity, cfg,
                     xp=jnp)


def push_frame(history: jax.Array, frame: jax.Array) -> jax.Array:
    """(history, frame_size) stack with `frame` inserted first and the oldest frame dropped."""
    return jnp.concatenate([frame[None], history[:-1]], axis=0)


def critic_obs(actor_obs: jax.Array, clean_frame: jax.Array, privileged: dict[str, jax.Array]) -> jax.Array:
    """Actor observation, its noise-free newest frame, and privileged state (sorted by name)."""
    return jnp.concatenate([actor_obs, clean_frame] + [jnp.ravel(privileged[k]) for k in sorted(privileged)])
