"""What an actuator-model parameter is (`ParameterDef`: unit, meaning, plausible range, default, fit bounds) and the
parameters every motor model shares; each motor model lists its own table (`toddlerbot.actuation.motor_models`).

Everything that names a model's parameters derives from its table: the model's parameter class
(`parameter_class`), hence the fields of a motors.yaml ``actuator`` entry and of a params.json and their checks
(`ParameterDef.check`), the fit's search bounds and scales (`toddlerbot.sysid.params`), the seeded perturbations of
`toddlerbot.sim.perturbation`, and the table in docs/sysid.md.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ParameterDef:
    """One actuator-model parameter, in joint units of the motor's output shaft. A name means one thing in every
    model that has it (`toddlerbot.actuation.motor_models` refuses two definitions of a name)."""

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
    perturbed: bool = False
    """Scaled by the seeded motor perturbations of the robustness trials (`toddlerbot.sim.perturbation`)."""

    def check(self, value: object) -> None:
        """Raise ValueError naming the parameter if ``value`` is not a plausible value of it."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ValueError(f"{self.name} must be a finite number >= 0, got {value!r}")
        if value >= self.maximum if self.below_maximum else value > self.maximum:
            raise ValueError(f"{self.name} must be {'below' if self.below_maximum else 'at most'} "
                             f"{self.maximum:g}, got {value:g}")
        if self.positive and value == 0:
            raise ValueError(f"{self.name} must be > 0, got {value}")


# The passive terms every motor model has: MuJoCo applies them from the joint (Eq. 6), the model builder sets them.
DAMPING = ParameterDef("damping", "N*m*s/rad", 1e-4, 0.05, True, 10.0,
                       "passive viscous resistance, powered or not (MuJoCo joint damping)", perturbed=True)
ARMATURE = ParameterDef("armature", "kg*m^2", 2e-4, 0.03, True, 1.0, "reflected rotor inertia (MuJoCo joint armature)",
                        perturbed=True)
FRICTIONLOSS = ParameterDef("frictionloss", "N*m", 1e-3, 0.3, True, 100.0,
                            "Coulomb friction at no load (MuJoCo joint frictionloss)", perturbed=True)
PASSIVE = (DAMPING, ARMATURE, FRICTIONLOSS)
LOAD_FRICTION = ParameterDef("load_friction", "N*m per N*m", 0.0, 0.8, False, 1.0,
                             "Coulomb friction per N*m of transmitted motor torque (1 - gearbox efficiency)",
                             default=0.0, below_maximum=True)
"""Gearbox friction growing with the transmitted torque, which both shipped models have."""


def check_parameters(params: object) -> None:
    """Raise ValueError naming the first field of a parameter class instance that is not plausible."""
    for definition in type(params).parameters:
        definition.check(getattr(params, definition.name))


def parameter_class(name: str, methods: type) -> type:
    """The frozen dataclass ``name`` whose float fields are ``methods.parameters`` (in order, with their defaults)
    and whose methods, class attributes and docstring are those of ``methods``."""
    fields = [(p.name, float) if p.default is None else (p.name, float, dataclasses.field(default=p.default))
              for p in methods.parameters]
    namespace = {"__module__": methods.__module__, "__doc__": methods.__doc__}
    return dataclasses.make_dataclass(name, fields, bases=(methods,), namespace=namespace, frozen=True)
