"""The appendix's actuator model (section 8.9, Eq. 8-10): a PD controller whose torque is limited by a
speed-dependent envelope, with the controller's own damping `kd_min` and a braking limit, plus the extended model's
stiction and load-dependent friction (0 by default: the 9-parameter model). Its parameter table, its coefficients
of the one torque law (`toddlerbot.actuation.model`) and its fits."""

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

APPENDIX_FIT = ("damping", "frictionloss", "armature", "tau_max", "q_dot_tau_max", "tau_q_dot_max", "q_dot_max",
                "kd_min", "tau_brake")
"""The 9 parameters of the appendix, in the order the fit's vector holds them."""


class _AppendixModel:
    """Parameters of the appendix's actuator model (Eq. 8-10), in joint units of the motor's output shaft (the
    extended friction terms default to the 9-parameter model)."""

    model: ClassVar[str] = "appendix"
    # name, unit, fit lower, fit upper, log scale, plausible maximum, meaning[, default, checks, searched as]
    parameters: ClassVar[tuple[ParameterDef, ...]] = (
        *PASSIVE,
        ParameterDef("tau_max", "N*m", 0.05, 6.0, True, 1000.0, "acceleration torque limit at low speed",
                     perturbed=True),
        ParameterDef("q_dot_tau_max", "rad/s", 0.0, 8.0, False, 1000.0, "speed up to which tau_max holds"),
        ParameterDef("q_dot_max", "rad/s", 0.2, 20.0, False, 1000.0,
                     "speed at which the acceleration limit has fallen to tau_q_dot_max", span_above="q_dot_tau_max",
                     perturbed=True),
        ParameterDef("tau_q_dot_max", "N*m", 0.0, 1.0, False, 1000.0,
                     "acceleration torque limit at q_dot_max and beyond", fraction_of="tau_max"),
        ParameterDef("kd_min", "N*m*s/rad", 0.01, 2.0, True, 100.0,
                     "damping the powered motor's controller adds (appendix Eq. 8)", perturbed=True),
        ParameterDef("tau_brake", "N*m", 0.05, 10.0, True, 1000.0, "braking torque limit (appendix Eq. 10)",
                     perturbed=True),
        # 173.8 / stall torque over the X series (docs/sysid.md), so the bounds span XM540 to XL330-M077
        ParameterDef("kp_scale", "firmware kp per N*m/rad", 15.0, 1000.0, True, 1e5,
                     "Dynamixel position P gain / physical stiffness (fitted with --fit-kp-scale)", positive=True),
        ParameterDef("stiction", "N*m", 1e-4, 0.3, True, 100.0,
                     "extended model: static friction above frictionloss at rest", default=0.0),
        ParameterDef("stribeck_velocity", "rad/s", 0.01, 3.0, True, 1000.0,
                     "extended model: speed over which stiction decays, exp(-(q_dot/v)^2)", default=0.1,
                     positive=True),
        LOAD_FRICTION,
    )
    fits: ClassVar[dict[str, Fit]] = {
        "appendix": Fit(APPENDIX_FIT, "kp_scale", {
            "stiction": "the 9-parameter model of the appendix has none", "stribeck_velocity": "no stiction",
            "load_friction": "the 9-parameter model of the appendix has none"}),
        "extended": Fit((*APPENDIX_FIT, "stiction", "stribeck_velocity", "load_friction"), "kp_scale"),
    }

    def __post_init__(self) -> None:
        check_parameters(self)
        if self.q_dot_max <= self.q_dot_tau_max:
            raise ValueError(f"q_dot_max ({self.q_dot_max}) must exceed q_dot_tau_max ({self.q_dot_tau_max})")

    def replace(self, **changes: float) -> ActuatorParams:
        return dataclasses.replace(self, **changes)

    def array_fields(self, kp_dynamixel: float, kd_dynamixel: float) -> dict[str, float]:
        """This motor's `toddlerbot.actuation.model.ActuatorArrays` entries at these firmware gains."""
        return self.fields_to_arrays(dataclasses.asdict(self), kp_dynamixel, kd_dynamixel)

    @staticmethod
    def fields_to_arrays(f: Mapping, kp_dynamixel, kd_dynamixel) -> dict:
        """`ActuatorArrays` entries from field values (floats, or arrays of candidates in a fit; constants stay
        scalars and broadcast): the parameters of the same name, physical gains from kp_scale, no back-EMF after
        the limit, a linear PWM."""
        same = {name: f[name] for name in ActuatorArrays._fields if name in f}
        return {**same, "kp": kp_dynamixel / f["kp_scale"], "kd": kd_dynamixel / f["kp_scale"],
                "back_emf_damping": 0.0, "pwm_exponent": 1.0}

    @classmethod
    def like(cls, p) -> ActuatorParams:
        """The appendix-model motor closest to a DC motor (`toddlerbot.actuation.dc_motor`): its stall torque
        falling linearly to zero at the no-load speed (Eq. 9 with the knee at rest), braking at the stall torque,
        its gain, no kd_min."""
        if p.model != "dc_motor":
            raise ValueError(f"an appendix fit starts from appendix or dc_motor parameters, not {p.model}; "
                             "give --start")
        return cls(damping=p.damping, armature=p.armature, frictionloss=p.frictionloss, tau_max=p.stall_torque,
                   q_dot_tau_max=0.0, q_dot_max=p.no_load_speed, tau_q_dot_max=0.0, kd_min=p.back_emf_damping,
                   tau_brake=p.stall_torque, kp_scale=p.kp_scale, load_friction=p.load_friction)


ActuatorParams = parameter_class("ActuatorParams", _AppendixModel)
