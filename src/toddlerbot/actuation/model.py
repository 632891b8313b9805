"""The actuator model (appendix Eq. 8-10), written once for numpy and JAX.

Every function takes the array namespace ``xp`` (``numpy`` by default, ``jax.numpy`` for MJX training), and
the parameters as an `ActuatorArrays` (a NamedTuple, hence a JAX pytree), one entry per motor.

* PD control (Eq. 8): tau_m = kp * (q_target - q) - (kd_min + kd) * q_dot, with physical gains
  kp = kp_dynamixel / kp_scale and kd = kd_dynamixel / kp_scale.
* Acceleration limit (Eq. 9 generalised): tau_max up to q_dot_tau_max, then falling linearly to tau_q_dot_max at
  q_dot_max, and tau_q_dot_max beyond (with tau_q_dot_max = 0 this is Eq. 9 exactly).
* Braking limit (Eq. 10): a torque that opposes the motion is limited by the constant tau_brake instead.
  (Eq. 10 as printed swaps the two bounds; we follow the appendix's text: braking torque is the larger one.)
* Passive resistance (Eq. 6): tau_r = frictionloss * sign(q_dot) + damping * q_dot, plus the armature (rotor
  inertia). In the simulator MuJoCo applies all three from the joint's frictionloss, damping and armature, which
  the model builder sets from the same parameters; `resistance_torque` is the same law for test-bed analysis.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import NamedTuple

import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams


class ActuatorArrays(NamedTuple):
    """Actuator-model parameters of n motors, each an array of shape (n,)."""

    kp: np.ndarray
    """Physical position gain, N*m/rad."""
    kd: np.ndarray
    """Physical derivative gain, N*m*s/rad."""
    kd_min: np.ndarray
    tau_max: np.ndarray
    q_dot_tau_max: np.ndarray
    q_dot_max: np.ndarray
    tau_q_dot_max: np.ndarray
    tau_brake: np.ndarray


def physical_gains(kp_dynamixel: float, kd_dynamixel: float, params: ActuatorParams) -> tuple[float, float]:
    """Dynamixel firmware gains -> (kp N*m/rad, kd N*m*s/rad)."""
    return kp_dynamixel / params.kp_scale, kd_dynamixel / params.kp_scale


def actuator_arrays(
    params: Sequence[ActuatorParams], kp_dynamixel: Sequence[float], kd_dynamixel: Sequence[float]
) -> ActuatorArrays:
    """Stack per-motor parameters and firmware gains into arrays (numpy; pass through jnp.asarray for JAX)."""
    gains = np.array([physical_gains(kp, kd, p) for p, kp, kd in zip(params, kp_dynamixel, kd_dynamixel, strict=True)])
    field = lambda name: np.array([getattr(p, name) for p in params], dtype=float)  # noqa: E731
    return ActuatorArrays(
        kp=gains[:, 0], kd=gains[:, 1], kd_min=field("kd_min"), tau_max=field("tau_max"),
        q_dot_tau_max=field("q_dot_tau_max"), q_dot_max=field("q_dot_max"),
        tau_q_dot_max=field("tau_q_dot_max"), tau_brake=field("tau_brake"),
    )


def acceleration_limit(q_dot, p: ActuatorArrays, xp: ModuleType = np):
    """Largest torque (N*m, >= 0) the motor can apply in the direction of its motion at speed q_dot (rad/s)."""
    speed = xp.abs(q_dot)
    fraction = xp.clip((speed - p.q_dot_tau_max) / (p.q_dot_max - p.q_dot_tau_max), 0.0, 1.0)
    return p.tau_max + fraction * (p.tau_q_dot_max - p.tau_max)


def pd_torque(q_target, q, q_dot, p: ActuatorArrays, xp: ModuleType = np):
    """Unlimited PD torque of Eq. 8, N*m."""
    return p.kp * (q_target - q) - (p.kd_min + p.kd) * q_dot


def torque_bounds(q_dot, p: ActuatorArrays, xp: ModuleType = np):
    """(lower, upper) torque the motor can apply at speed q_dot (rad/s), N*m (Eq. 9-10).

    Along the motion the acceleration limit applies, against it the braking limit tau_brake; at rest both
    directions accelerate.
    """
    accel = acceleration_limit(q_dot, p, xp)
    upper = xp.where(q_dot < 0, p.tau_brake, accel)
    lower = -xp.where(q_dot > 0, p.tau_brake, accel)
    return lower, upper


def limit_torque(tau, q_dot, p: ActuatorArrays, xp: ModuleType = np):
    """Clamp a commanded torque: the acceleration limit along the motion, tau_brake against it (Eq. 9-10)."""
    lower, upper = torque_bounds(q_dot, p, xp)
    return xp.clip(tau, lower, upper)


def motor_torque(q_target, q, q_dot, p: ActuatorArrays, xp: ModuleType = np):
    """Torque the motor applies to its joint (before MuJoCo's passive resistance), N*m."""
    return limit_torque(pd_torque(q_target, q, q_dot, p, xp), q_dot, p, xp)


def resistance_torque(q_dot, damping, frictionloss, xp: ModuleType = np):
    """Passive resistance of Eq. 6 (N*m, opposing positive q_dot): frictionloss * sign(q_dot) + damping * q_dot."""
    return frictionloss * xp.sign(q_dot) + damping * q_dot
