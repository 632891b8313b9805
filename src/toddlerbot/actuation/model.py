"""The actuator model (appendix Eq. 8-10), written once for numpy and JAX.

Every function takes the array namespace ``xp`` (``numpy`` by default, ``jax.numpy`` for MJX training), and
the parameters as an `ActuatorArrays` (a NamedTuple, hence a JAX pytree), one entry per motor.

* PD control (Eq. 8): tau_m = kp * (q_target - q) - (kd_min + kd) * q_dot, with physical gains
  kp = kp_dynamixel / kp_scale and kd = kd_dynamixel / kp_scale.
* Acceleration limit (Eq. 9 generalised): tau_max up to q_dot_tau_max, then falling linearly to tau_q_dot_max at
  q_dot_max, and tau_q_dot_max beyond (with tau_q_dot_max = 0 this is Eq. 9 exactly).
* Braking limit (Eq. 10): a torque that opposes the motion is limited by the constant tau_brake instead.
  (Eq. 10 as printed swaps the two bounds; we follow the appendix's text: braking torque is the larger one.)
* Extended friction (optional; all zero in the appendix's 9-parameter model, which it then equals exactly): on
  top of MuJoCo's Coulomb friction loss, static friction that exceeds it by ``stiction`` at rest and decays with
  the Stribeck velocity, and gearbox friction growing with the transmitted torque (``load_friction`` x |tau|):
  tau_f = (stiction * exp(-(q_dot / stribeck_velocity)^2) + load_friction * |tau|) * tanh(q_dot / FRICTION_SMOOTHING).
  The tanh makes it smooth (and jit/vmap-safe) at zero speed; holding at rest is left to MuJoCo's frictionloss
  constraint, so this term only shapes friction once the shaft moves. `motor_torque` subtracts it, so the
  simulator and the MJX environment apply it without change.
* Supply voltage (`at_voltage`): a DC motor's stall torque and no-load speed are both proportional to its supply
  voltage, and the PD output is a PWM duty (a fraction of the supply), so at s = V / V_rated the torque limits,
  the speed breakpoints and the physical gains kp, kd all scale by s; kd_min (back-EMF damping Kt*Ke/R) does not.
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
    stiction: np.ndarray
    """Static friction above frictionloss at rest, N*m (extended model; 0 in the appendix model)."""
    stribeck_velocity: np.ndarray
    """rad/s, > 0."""
    load_friction: np.ndarray
    """Friction per N*m of motor torque, 1 (extended model; 0 in the appendix model)."""


FRICTION_SMOOTHING = 0.02
"""rad/s: speed scale of the tanh that replaces sign(q_dot) in the extended friction. Small enough to act like
sign() beyond a few hundredths of rad/s; large enough that the explicit 1 ms step stays stable (the friction slope
stiction / FRICTION_SMOOTHING stays far below armature / dt for the catalogue's motors)."""


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
        tau_q_dot_max=field("tau_q_dot_max"), tau_brake=field("tau_brake"), stiction=field("stiction"),
        stribeck_velocity=field("stribeck_velocity"), load_friction=field("load_friction"),
    )


def at_voltage(p: ActuatorArrays, voltage_ratio, xp: ModuleType = np) -> ActuatorArrays:
    """The parameters at supply voltage ``voltage_ratio`` x the catalogue's rated voltage (see module docstring)."""
    s = xp.asarray(voltage_ratio)
    return p._replace(
        kp=p.kp * s, kd=p.kd * s, tau_max=p.tau_max * s, q_dot_tau_max=p.q_dot_tau_max * s,
        q_dot_max=p.q_dot_max * s, tau_q_dot_max=p.tau_q_dot_max * s, tau_brake=p.tau_brake * s,
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


def extra_friction(q_dot, tau, p: ActuatorArrays, xp: ModuleType = np):
    """Extended friction (N*m, opposing positive q_dot) on top of the Coulomb friction loss, for a motor
    transmitting torque ``tau`` (0 when unpowered): Stribeck static friction plus load-dependent friction."""
    stribeck = p.stiction * xp.exp(-((q_dot / p.stribeck_velocity) ** 2))
    return (stribeck + p.load_friction * xp.abs(tau)) * xp.tanh(q_dot / FRICTION_SMOOTHING)


def motor_torque(q_target, q, q_dot, p: ActuatorArrays, xp: ModuleType = np):
    """Torque the motor applies to its joint (before MuJoCo's passive resistance), N*m: the limited PD torque
    minus the extended friction (exactly the limited PD torque in the appendix's model)."""
    tau = limit_torque(pd_torque(q_target, q, q_dot, p, xp), q_dot, p, xp)
    return tau - extra_friction(q_dot, tau, p, xp)


def passive_torque(q_dot, p: ActuatorArrays, xp: ModuleType = np):
    """Torque of an unpowered (torque-off) motor beyond MuJoCo's passive terms, N*m: no PD torque, no kd_min,
    only the extended static friction (0 in the appendix's model)."""
    return -extra_friction(q_dot, 0.0, p, xp)


def resistance_torque(q_dot, damping, frictionloss, xp: ModuleType = np):
    """Passive resistance of Eq. 6 (N*m, opposing positive q_dot): frictionloss * sign(q_dot) + damping * q_dot."""
    return frictionloss * xp.sign(q_dot) + damping * q_dot
