"""The actuator model, written once for numpy, JAX and numba: the appendix's (Eq. 8-10) and the DC-motor model.

Every function takes the array namespace ``xp`` (``numpy`` when None, ``jax.numpy`` for MJX training; the
simulator's substep loop compiles the numpy form with numba, which needs the namespace left out), and
the parameters as an `ActuatorArrays` (a NamedTuple, hence a JAX pytree), one entry per motor. Both models are
one torque law with per-motor coefficients, so a robot can mix them (e.g. one fitted DC-motor file):

* PD control (Eq. 8): tau_pd = kp * (q_target - q) - (kd_min + kd) * q_dot, with physical gains from the firmware
  gains (appendix: kp = kp_dynamixel / kp_scale; DC motor: the PWM duty the firmware sets times the stall torque).
* Drive limit (Eq. 9-10): tau_max up to q_dot_tau_max, then falling linearly to tau_q_dot_max at q_dot_max along
  the motion; tau_brake against it (Eq. 10 as printed swaps the two bounds; we follow the appendix's text). The DC
  motor's limit is the stall torque at full PWM duty in both directions (tau_max = tau_q_dot_max = tau_brake).
* PWM shape (DC motor): the torque grows as duty^pwm_exponent, duty = tau / tau_max (exponent 1: linear, and the
  appendix's model, whose torque is then left exactly as it is).
* Back-EMF (DC motor): - back_emf_damping * q_dot after the limit, as the winding sees duty * V - k_e * q_dot, so
  the available torque falls linearly to zero at the no-load speed and grows when braking (0 in the appendix).
* Coulomb friction (`friction_excess`): MuJoCo's joint frictionloss plus static friction (``stiction``, decaying
  with the Stribeck velocity) and gearbox friction growing with the transmitted motor torque
  (``load_friction`` x |tau|). It is a friction *budget*: the shaft sticks while the net torque is below it, which
  is how a loaded gearbox holds a pendulum. The simulators add `friction_excess` to the joint's frictionloss every
  step (0 in the appendix's model, where the joint's frictionloss alone applies).
* Supply voltage (`at_voltage`): stall torque, no-load speed and the PWM output all scale with the supply, so at
  s = V / V_rated the torque limits, the speed breakpoints and the physical gains kp, kd scale by s, while kd_min and
  the back-EMF damping (k_t k_e / R) do not.
* Passive resistance (Eq. 6): tau_r = frictionloss * sign(q_dot) + damping * q_dot, plus the armature (rotor
  inertia). In the simulator MuJoCo applies all three from the joint's frictionloss, damping and armature, which
  the model builder sets from the same parameters; `resistance_torque` is the same law for test-bed analysis.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import NamedTuple

import numpy as np

from toddlerbot.actuation.motor_params import MotorParams


class ActuatorArrays(NamedTuple):
    """The torque law's coefficients for n motors, each an array of shape (n,). An entry named like a parameter of a
    motor model's table (`toddlerbot.actuation.motor_models`) has its unit and, for the appendix model, its value
    (each model's ``fields_to_arrays`` fills them)."""

    kp: np.ndarray
    """Physical position gain, N*m/rad."""
    kd: np.ndarray
    """Physical derivative gain, N*m*s/rad."""
    kd_min: np.ndarray
    """Damping inside the drive limit, N*m*s/rad (appendix Eq. 8; 0 for the DC motor)."""
    tau_max: np.ndarray
    q_dot_tau_max: np.ndarray
    q_dot_max: np.ndarray
    tau_q_dot_max: np.ndarray
    tau_brake: np.ndarray
    back_emf_damping: np.ndarray
    """Damping after the drive limit, N*m*s/rad: the DC motor's back-EMF (0 in the appendix model)."""
    pwm_exponent: np.ndarray
    """Torque grows as PWM duty^pwm_exponent, 1 (1: linear, as in the appendix model)."""
    stiction: np.ndarray
    """Static friction above frictionloss at rest, N*m (0 in the appendix model)."""
    stribeck_velocity: np.ndarray
    """rad/s, > 0."""
    load_friction: np.ndarray
    """Coulomb friction per N*m of motor torque, 1 (0 in the appendix model)."""


def actuator_arrays(
    params: Sequence[MotorParams], kp_dynamixel: Sequence[float], kd_dynamixel: Sequence[float]
) -> ActuatorArrays:
    """Stack per-motor parameters and firmware gains into arrays (numpy; pass through jnp.asarray for JAX)."""
    rows = [p.array_fields(kp, kd) for p, kp, kd in zip(params, kp_dynamixel, kd_dynamixel, strict=True)]
    return ActuatorArrays(**{name: np.array([row[name] for row in rows], dtype=float)
                             for name in ActuatorArrays._fields})


def at_voltage(p: ActuatorArrays, voltage_ratio, xp: ModuleType | None = None) -> ActuatorArrays:
    """The parameters at supply voltage ``voltage_ratio`` x the catalogue's rated voltage (see module docstring)."""
    xp = np if xp is None else xp
    s = xp.asarray(voltage_ratio)
    return p._replace(
        kp=p.kp * s, kd=p.kd * s, tau_max=p.tau_max * s, q_dot_tau_max=p.q_dot_tau_max * s,
        q_dot_max=p.q_dot_max * s, tau_q_dot_max=p.tau_q_dot_max * s, tau_brake=p.tau_brake * s,
    )


def acceleration_limit(q_dot, p: ActuatorArrays, xp: ModuleType | None = None):
    """Largest drive torque (N*m, >= 0) in the direction of the motion at speed q_dot (rad/s), before back-EMF."""
    xp = np if xp is None else xp
    speed = xp.abs(q_dot)
    fraction = xp.clip((speed - p.q_dot_tau_max) / (p.q_dot_max - p.q_dot_tau_max), 0.0, 1.0)
    return p.tau_max + fraction * (p.tau_q_dot_max - p.tau_max)


def pd_torque(q_target, q, q_dot, p: ActuatorArrays, xp: ModuleType | None = None):
    """Unlimited PD torque of Eq. 8, N*m."""
    return p.kp * (q_target - q) - (p.kd_min + p.kd) * q_dot


def drive_bounds(q_dot, p: ActuatorArrays, xp: ModuleType | None = None):
    """(lower, upper) limit of the drive torque at speed q_dot (rad/s), N*m (Eq. 9-10): along the motion the
    acceleration limit, against it the braking limit tau_brake; at rest both directions accelerate."""
    xp = np if xp is None else xp
    accel = acceleration_limit(q_dot, p, xp)
    upper = xp.where(q_dot < 0, p.tau_brake, accel)
    lower = -xp.where(q_dot > 0, p.tau_brake, accel)
    return lower, upper


def torque_bounds(q_dot, p: ActuatorArrays, xp: ModuleType | None = None):
    """(lower, upper) torque the motor can apply at speed q_dot (rad/s), N*m: the drive limit shifted by the
    back-EMF (the appendix's Eq. 9-10 exactly where there is none)."""
    xp = np if xp is None else xp
    lower, upper = drive_bounds(q_dot, p, xp)
    return lower - p.back_emf_damping * q_dot, upper - p.back_emf_damping * q_dot


def limit_torque(tau, q_dot, p: ActuatorArrays, xp: ModuleType | None = None):
    """Clamp a commanded torque to the drive limit: acceleration limit along the motion, tau_brake against it."""
    xp = np if xp is None else xp
    lower, upper = drive_bounds(q_dot, p, xp)
    return xp.clip(tau, lower, upper)


def pwm_shape(tau, p: ActuatorArrays, xp: ModuleType | None = None):
    """Drive torque of a PWM duty tau / tau_max raised to pwm_exponent, N*m; tau itself, bit for bit, where the
    exponent is 1 (the appendix's model)."""
    xp = np if xp is None else xp
    duty = xp.abs(tau) / p.tau_max
    return xp.where(p.pwm_exponent == 1.0, tau, xp.sign(tau) * p.tau_max * duty**p.pwm_exponent)


def motor_torque(q_target, q, q_dot, p: ActuatorArrays, xp: ModuleType | None = None):
    """Torque the motor applies to its joint (before MuJoCo's passive resistance and the Coulomb friction budget),
    N*m: the limited, PWM-shaped PD torque minus the back-EMF damping (the appendix's limited PD torque exactly
    where there is neither)."""
    xp = np if xp is None else xp
    tau = pwm_shape(limit_torque(pd_torque(q_target, q, q_dot, p, xp), q_dot, p, xp), p, xp)
    return tau - p.back_emf_damping * q_dot


def friction_excess(q_dot, tau, p: ActuatorArrays, xp: ModuleType | None = None):
    """Coulomb friction (N*m, >= 0) on top of the joint's frictionloss, for a motor applying torque ``tau``
    (0 when unpowered): Stribeck static friction plus load-dependent gearbox friction. 0 in the appendix model."""
    xp = np if xp is None else xp
    return p.stiction * xp.exp(-((q_dot / p.stribeck_velocity) ** 2)) + p.load_friction * xp.abs(tau)


def has_friction_excess(p: ActuatorArrays) -> bool:
    """Whether any motor's Coulomb friction changes with speed or torque (else the joint's frictionloss is all)."""
    return bool(np.any(np.asarray(p.stiction)) or np.any(np.asarray(p.load_friction)))


def resistance_torque(q_dot, damping, frictionloss, xp: ModuleType | None = None):
    """Passive resistance of Eq. 6 (N*m, opposing positive q_dot): frictionloss * sign(q_dot) + damping * q_dot."""
    xp = np if xp is None else xp
    return frictionloss * xp.sign(q_dot) + damping * q_dot
