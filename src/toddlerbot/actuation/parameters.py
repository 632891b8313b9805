"""The one table of actuator-model parameters: each one's unit, meaning, plausible range, default and fit bounds.

Everything that names the parameters derives from `PARAMETERS`: the parameter classes of both actuator models
(`parameter_class`: `toddlerbot.actuation.catalogue.ActuatorParams`, `toddlerbot.actuation.dc_motor.DCMotorParams`),
hence the fields of a motors.yaml ``actuator`` entry and of a params.json and their checks (`ParameterDef.check`),
and the fit's search bounds and scales (`toddlerbot.sysid.params`). docs/sysid.md shows the table.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

APPENDIX = "appendix"
DC_MOTOR = "dc_motor"
BOTH = (APPENDIX, DC_MOTOR)


@dataclass(frozen=True)
class ParameterDef:
    """One actuator-model parameter, in joint units of the motor's output shaft."""

    name: str
    unit: str
    lower: float
    """Lower fit bound: where the fit starts looking (of the span or fraction it searches, see `span_above`)."""
    upper: float
    """Upper fit bound."""
    log: bool
    """The fit searches it on a log scale (positive and spanning decades), else linearly."""
    maximum: float
    """Largest plausible value: a motors.yaml or params.json beyond it is refused (finite is not enough: tau_max
    1e300 is finite). Orders of magnitude above the fit bounds and any Dynamixel's figure."""
    models: tuple[str, ...]
    """The actuator models that have it."""
    doc: str
    default: float | None = None
    """Value where a motors.yaml entry or params.json leaves it out (None: required)."""
    positive: bool = False
    """Must be > 0 (else >= 0)."""
    below_maximum: bool = False
    """Must stay below `maximum`, not reach it."""
    span_above: str = ""
    """The fit searches the span above this parameter, not the value (so the value stays above it)."""
    fraction_of: str = ""
    """The fit searches the fraction of this parameter, not the value."""

    def check(self, value: object) -> None:
        """Raise ValueError naming the parameter if ``value`` is not a plausible value of it."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ValueError(f"{self.name} must be a finite number >= 0, got {value!r}")
        if value >= self.maximum if self.below_maximum else value > self.maximum:
            raise ValueError(f"{self.name} must be {'below' if self.below_maximum else 'at most'} "
                             f"{self.maximum:g}, got {value:g}")
        if self.positive and value == 0:
            raise ValueError(f"{self.name} must be > 0, got {value}")


PARAMETERS: dict[str, ParameterDef] = {p.name: p for p in (
    # name, unit, fit lower, fit upper, log scale, plausible maximum, models, meaning[, default, checks, searched as]
    ParameterDef("damping", "N*m*s/rad", 1e-4, 0.05, True, 10.0, BOTH,
                 "passive viscous resistance, powered or not (MuJoCo joint damping)"),
    ParameterDef("armature", "kg*m^2", 2e-4, 0.03, True, 1.0, BOTH, "reflected rotor inertia (MuJoCo joint armature)"),
    ParameterDef("frictionloss", "N*m", 1e-3, 0.3, True, 100.0, BOTH,
                 "Coulomb friction at no load (MuJoCo joint frictionloss)"),
    ParameterDef("tau_max", "N*m", 0.05, 6.0, True, 1000.0, (APPENDIX,), "acceleration torque limit at low speed"),
    ParameterDef("q_dot_tau_max", "rad/s", 0.0, 8.0, False, 1000.0, (APPENDIX,), "speed up to which tau_max holds"),
    ParameterDef("q_dot_max", "rad/s", 0.2, 20.0, False, 1000.0, (APPENDIX,),
                 "speed at which the acceleration limit has fallen to tau_q_dot_max", span_above="q_dot_tau_max"),
    ParameterDef("tau_q_dot_max", "N*m", 0.0, 1.0, False, 1000.0, (APPENDIX,),
                 "acceleration torque limit at q_dot_max and beyond", fraction_of="tau_max"),
    ParameterDef("kd_min", "N*m*s/rad", 0.01, 2.0, True, 100.0, (APPENDIX,),
                 "damping the powered motor's controller adds (appendix Eq. 8)"),
    ParameterDef("tau_brake", "N*m", 0.05, 10.0, True, 1000.0, (APPENDIX,), "braking torque limit (appendix Eq. 10)"),
    # 173.8 / stall torque over the X series (docs/sysid.md), so the bounds span XM540 to XL330-M077
    ParameterDef("kp_scale", "firmware kp per N*m/rad", 15.0, 1000.0, True, 1e5, (APPENDIX,),
                 "Dynamixel position P gain / physical stiffness (fitted with --fit-kp-scale)", positive=True),
    ParameterDef("stiction", "N*m", 1e-4, 0.3, True, 100.0, (APPENDIX,),
                 "extended model: static friction above frictionloss at rest", default=0.0),
    ParameterDef("stribeck_velocity", "rad/s", 0.01, 3.0, True, 1000.0, (APPENDIX,),
                 "extended model: speed over which stiction decays, exp(-(q_dot/v)^2)", default=0.1, positive=True),
    ParameterDef("stall_torque", "N*m", 0.05, 10.0, True, 1000.0, (DC_MOTOR,),
                 "torque at full PWM duty and rest, at the rated voltage (k_t V / R)", positive=True),
    ParameterDef("no_load_speed", "rad/s", 1.0, 100.0, True, 1000.0, (DC_MOTOR,),
                 "speed at which the back-EMF cancels the full rated supply (V / k_e)", positive=True),
    ParameterDef("pwm_per_rad", "duty per rad per firmware kp", 2e-4, 0.05, True, 10.0, (DC_MOTOR,),
                 "PWM duty (1 = 100 %) per rad of error per unit of firmware kp (fitted with --fit-kp-scale)",
                 positive=True),
    ParameterDef("pwm_exponent", "1", 0.5, 1.5, False, 3.0, (DC_MOTOR,),
                 "the drive torque grows as duty^pwm_exponent", default=1.0, positive=True),
    ParameterDef("load_friction", "N*m per N*m", 0.0, 0.8, False, 1.0, BOTH,
                 "Coulomb friction per N*m of transmitted motor torque (1 - gearbox efficiency)", default=0.0,
                 below_maximum=True),
)}
"""Every actuator-model parameter, in the field order of the models' classes (params.json writes them so)."""


def parameters_of(model: str) -> tuple[ParameterDef, ...]:
    """``model``'s parameters in table order."""
    return tuple(p for p in PARAMETERS.values() if model in p.models)


def check_parameters(params: object) -> None:
    """Raise ValueError naming the first field of a parameter class instance that is not plausible."""
    for field in dataclasses.fields(params):
        PARAMETERS[field.name].check(getattr(params, field.name))


def parameter_class(name: str, methods: type) -> type:
    """The frozen dataclass ``name`` whose float fields are the parameters of ``methods.model`` (table order, the
    table's defaults) and whose methods and docstring are those of ``methods``."""
    fields = [(p.name, float) if p.default is None else (p.name, float, dataclasses.field(default=p.default))
              for p in parameters_of(methods.model)]
    namespace = {"__module__": methods.__module__, "__doc__": methods.__doc__}
    return dataclasses.make_dataclass(name, fields, bases=(methods,), namespace=namespace, frozen=True)
