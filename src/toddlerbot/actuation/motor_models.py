"""Motor models found by name, each one registration carrying its whole bundle: its parameter class, whose class
attributes are the model's parameter table (``parameters``), its torque law (``fields_to_arrays``: the model's
parameters as the coefficients of the one torque law of `toddlerbot.actuation.model`, for numpy, JAX and the
compiled substep loop alike), its fits (``fits``: what `sysid fit --model` fits, in which order) and how it starts a
fit from another model's parameters (``like``).

A catalogue entry or params.json names its model in ``model`` (default ``appendix``). Installed packages add models
through the entry-point group ``toddlerbot.motor_models``; a script calls `MOTOR_MODELS.register`. Everything else
that names parameters (the fit's search cube, the perturbations, docs/sysid.md) is generated from the registered
tables (`all_parameters`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from toddlerbot.actuation.parameters import ParameterDef
from toddlerbot.errors import ToddlerbotError
from toddlerbot.registry import Registry

DEFAULT_MOTOR_MODEL = "appendix"
"""The model of a catalogue entry or params.json that names none."""


@dataclass(frozen=True)
class Fit:
    """One way `sysid fit --model NAME` fits a motor model."""

    fitted: tuple[str, ...]
    """The parameters always fitted, in the CMA-ES vector's order (reordering them changes a seeded fit)."""
    gain_parameter: str
    """The firmware-to-physical gain conversion, fitted with ``--fit-kp-scale`` (else kept from the start)."""
    fixed: Mapping[str, str] = field(default_factory=dict)
    """Parameters of the model the fit leaves as they start, with the reason."""


MOTOR_MODELS = Registry("motor model", entry_point_group="toddlerbot.motor_models")
"""Model name -> its parameter class (`parameters`, `fits`, `fields_to_arrays`, `like`)."""
MOTOR_MODELS.register("appendix", "toddlerbot.actuation.appendix:ActuatorParams")
MOTOR_MODELS.register("dc_motor", "toddlerbot.actuation.dc_motor:DCMotorParams")


def motor_model(name: str) -> type:
    """The parameter class of the model registered as `name` (one line naming the known ones otherwise)."""
    return MOTOR_MODELS.get(name)


def all_parameters() -> dict[str, ParameterDef]:
    """Every registered model's parameters by name, in registration and table order; a name that two models define
    differently is refused in one line."""
    table: dict[str, ParameterDef] = {}
    for name in MOTOR_MODELS.names():
        for definition in motor_model(name).parameters:
            known = table.setdefault(definition.name, definition)
            if known != definition:
                raise ToddlerbotError(f"motor model {name!r}: parameter {definition.name!r} differs from another "
                                      "model's definition of it; a parameter name means one thing")
    return table


def fits() -> dict[str, tuple[type, Fit]]:
    """Every registered model's fits by name: fit name -> (parameter class, `Fit`)."""
    out: dict[str, tuple[type, Fit]] = {}
    for name in MOTOR_MODELS.names():
        cls = motor_model(name)
        for fit_name, fit in cls.fits.items():
            if fit_name in out:
                raise ToddlerbotError(f"motor model {name!r}: a fit named {fit_name!r} is already registered")
            out[fit_name] = (cls, fit)
    return out
