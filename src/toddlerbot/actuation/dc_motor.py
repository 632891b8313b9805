"""The DC-motor actuator model: the Dynamixel firmware's P controller setting a PWM duty on a DC motor.

The firmware turns the position error into a PWM duty, ``duty = clip(pwm_per_rad * kp * (q_target - q), -1, 1)``
(kp in firmware units: the X-series divides the gain by a constant and the error is in encoder counts, so
``pwm_per_rad`` is one number per firmware; ``motors.yaml`` gives the XL330's, with its source). The winding
then sees ``duty * V - k_e * q_dot``, so at the output shaft

    tau = stall_torque * sign(duty) |duty|^pwm_exponent - (stall_torque / no_load_speed) * q_dot,

with the stall torque ``k_t V / R`` and the no-load speed ``V / k_e`` both at the motor's rated voltage (the
e-Manual's figures; `toddlerbot.actuation.model.at_voltage` scales both with the supply). The same parameters hold
for every firmware gain: kp enters in its own units. Coulomb friction is a budget that grows with the transmitted
torque (``load_friction``), so a loaded gearbox holds its load.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import ClassVar

from toddlerbot.actuation.model import ActuatorArrays
from toddlerbot.actuation.motor_models import Fit
from toddlerbot.actuation.parameters import (
    LOAD_FRICTION,
    PASSIVE,
    ParameterDef,
    check_parameters,
    parameter_class,
)


class _DCMotorModel:
    """Parameters of the DC-motor model, in joint units of the motor's output shaft."""

    model: ClassVar[str] = "dc_motor"
    parameters: ClassVar[tuple[ParameterDef, ...]] = (
        *PASSIVE,
        ParameterDef("stall_torque", "N*m", 0.05, 10.0, True, 1000.0,
                     "torque at full PWM duty and rest, at the rated voltage (k_t V / R)", positive=True,
                     perturbed=True),
        ParameterDef("no_load_speed", "rad/s", 1.0, 100.0, True, 1000.0,
                     "speed at which the back-EMF cancels the full rated supply (V / k_e)", positive=True,
                     perturbed=True),
        ParameterDef("pwm_per_rad", "duty per rad per firmware kp", 2e-4, 0.05, True, 10.0,
                     "PWM duty (1 = 100 %) per rad of error per unit of firmware kp (fitted with --fit-kp-scale)",
                     positive=True),
        ParameterDef("pwm_exponent", "1", 0.5, 1.5, False, 3.0, "the drive torque grows as duty^pwm_exponent",
                     default=1.0, positive=True),
        LOAD_FRICTION,
    )
    fits: ClassVar[dict[str, Fit]] = {
        "dc_motor": Fit(("stall_torque", "no_load_speed", "pwm_exponent", "load_friction", "frictionloss", "damping",
                         "armature"), "pwm_per_rad"),
    }

    def __post_init__(self) -> None:
        check_parameters(self)

    @property
    def tau_max(self) -> float:
        """Torque from rest at full duty, N*m."""
        return self.stall_torque

    @property
    def tau_brake(self) -> float:
        """Braking torque at full duty from the no-load speed (stall torque plus as much back-EMF), N*m."""
        return 2.0 * self.stall_torque

    @property
    def q_dot_max(self) -> float:
        """The no-load speed, rad/s."""
        return self.no_load_speed

    @property
    def kp_scale(self) -> float:
        """Firmware kp per N*m/rad of physical stiffness (the appendix model's conversion factor)."""
        return 1.0 / (self.pwm_per_rad * self.stall_torque)

    @property
    def back_emf_damping(self) -> float:
        """k_t k_e / R = stall torque / no-load speed, N*m*s/rad (independent of the supply)."""
        return self.stall_torque / self.no_load_speed

    def array_fields(self, kp_dynamixel: float, kd_dynamixel: float) -> dict[str, float]:
        """This motor's `toddlerbot.actuation.model.ActuatorArrays` entries at these firmware gains."""
        return self.fields_to_arrays(dataclasses.asdict(self), kp_dynamixel, kd_dynamixel)

    @staticmethod
    def fields_to_arrays(f: Mapping, kp_dynamixel, kd_dynamixel) -> dict:
        """`ActuatorArrays` entries from field values (floats, or arrays of candidates in a fit; constants stay
        scalars and broadcast): the parameters of the same name, PD on the duty (the firmware's D gain taken in the
        units of kp), a flat limit at the stall torque, the back-EMF after it, load-dependent friction only."""
        same = {name: f[name] for name in ActuatorArrays._fields if name in f}
        per_unit = f["pwm_per_rad"] * f["stall_torque"]
        return {
            **same, "kp": kp_dynamixel * per_unit, "kd": kd_dynamixel * per_unit, "kd_min": 0.0,
            "tau_max": f["stall_torque"], "q_dot_tau_max": 0.0, "q_dot_max": f["no_load_speed"],
            "tau_q_dot_max": f["stall_torque"], "tau_brake": f["stall_torque"],
            "back_emf_damping": f["stall_torque"] / f["no_load_speed"], "stiction": 0.0, "stribeck_velocity": 1.0,
        }

    def replace(self, **changes: float) -> DCMotorParams:
        return dataclasses.replace(self, **changes)

    @classmethod
    def like(cls, p) -> DCMotorParams:
        """The DC motor closest to an appendix-model motor (`toddlerbot.actuation.appendix`): its torque from rest
        and physical gain, the no-load speed where its torque-speed line (through the two breakpoints of Eq. 9)
        reaches zero, its passive terms."""
        if p.model != "appendix":
            raise ValueError(f"a dc_motor fit starts from dc_motor or appendix parameters, not {p.model}; "
                             "give --start")
        slope = (p.tau_max - p.tau_q_dot_max) / (p.q_dot_max - p.q_dot_tau_max)
        no_load = p.q_dot_tau_max + p.tau_max / slope if slope > 0 else p.q_dot_max
        return cls(damping=p.damping, armature=p.armature, frictionloss=p.frictionloss, stall_torque=p.tau_max,
                   no_load_speed=no_load, pwm_per_rad=1.0 / (p.kp_scale * p.tau_max), load_friction=p.load_friction)


DCMotorParams = parameter_class("DCMotorParams", _DCMotorModel)
