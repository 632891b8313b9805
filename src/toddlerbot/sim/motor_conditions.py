"""The robot's motors under each motor model the project offers, and moved by a fit's standard errors: the
conditions of the motor-model sensitivity of walking (`benchmarks/bench_motor_models.py`; docs/sysid.md "Walking
under each motor model").

The robot's motors carry the appendix model (motors.yaml, appendix Table 3). Under another model each motor keeps
what Table 3 gives and takes the terms Table 3 lacks from a reference fit of that model: the fits of the real
XL330-M288 pendulum logs (`benchmarks/results/xl330_fits/`), a motor the robot does not use, so this is a
sensitivity study, not a transfer of fitted numbers:

- ``appendix``: Table 3;
- ``extended``: Table 3 plus the reference's stiction (scaled by the datasheet stall torques) and Stribeck velocity;
- ``dc_motor``: `DCMotorParams.like` Table 3 (the same torque from rest and physical gain, back-EMF instead of
  Eq. 9's line) plus the reference's PWM exponent;
- ``extended + load friction``, ``dc_motor + load friction``: with the reference's load friction too, a gearbox
  friction growing with the torque on top of Table 3, whose torque limits were identified without one.

``weaker`` and ``stronger`` move every parameter the reference fit identifies (relative standard error below
`IDENTIFIED`) by ``k`` of its relative standard errors, each in the direction that takes torque from the motion or
gives it (`DRIVE`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from toddlerbot.actuation.catalogue import Catalogue, default_catalogue
from toddlerbot.actuation.dc_motor import DCMotorParams
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.actuation.params_file import load_params, relative_errors
from toddlerbot.errors import ToddlerbotError
from toddlerbot.robot.description import RobotDescription

MODELS = ("appendix", "extended", "dc_motor")
"""The motor models the robot's motors are walked under, each with its reference fit ``<model>.json``."""
MOVES = ("weaker", "stronger")
IDENTIFIED = 0.5
"""Largest relative standard error of a parameter the reference fit identifies; the others are not moved (a move by
an error of 100 % or more could end at zero or below)."""
DRIVE = frozenset({"tau_max", "tau_q_dot_max", "q_dot_tau_max", "q_dot_max", "tau_brake", "stall_torque",
                   "no_load_speed", "pwm_per_rad"})
"""Parameters that give the motion more torque when raised; raising any other one (friction, damping, armature,
kd_min, kp_scale, pwm_exponent, Stribeck velocity) takes torque from it."""


@dataclass(frozen=True)
class ReferenceFit:
    """One model's fit of a reference motor: its parameters, their relative standard errors and the motor's
    datasheet stall torque (N*m), by which torques are scaled to another motor."""

    params: MotorParams
    relative_error: Mapping[str, float]
    stall_torque_nm: float

    @classmethod
    def load(cls, path: str | Path, catalogue: Catalogue | None = None) -> ReferenceFit:
        """The fit in a params.json written by `sysid fit` (with its standard errors)."""
        catalogue = catalogue or default_catalogue()
        name, params = load_params(path, catalogue)
        return cls(params, relative_errors(path), catalogue[name].stall_torque_nm)

    @property
    def identified(self) -> dict[str, float]:
        """Relative standard error of each parameter the fit identifies."""
        return {name: error for name, error in self.relative_error.items() if error < IDENTIFIED}


def under_model(params: MotorParams, stall_torque_nm: float, reference: ReferenceFit,
                load_friction: bool = False) -> MotorParams:
    """An appendix-model motor (``params``, datasheet stall torque ``stall_torque_nm``) under the reference's model,
    its missing terms from the reference (module docstring), the load friction only if ``load_friction``."""
    if params.model != "appendix":
        raise ToddlerbotError(f"a motor-model condition starts from the appendix model, not {params.model}")
    ref = reference.params
    load = {"load_friction": ref.load_friction} if load_friction else {}
    if ref.model == "dc_motor":
        return DCMotorParams.like(params).replace(pwm_exponent=ref.pwm_exponent, **load)
    return params.replace(stiction=ref.stiction * stall_torque_nm / reference.stall_torque_nm,
                          stribeck_velocity=ref.stribeck_velocity, **load)


def moved(params: MotorParams, relative_error: Mapping[str, float], k: float) -> MotorParams:
    """``params`` with each named parameter times ``1 + k * error``, raised for `DRIVE` and lowered for the others
    when ``k`` > 0 (a stronger motor), the reverse when ``k`` < 0."""
    return params.replace(**{name: getattr(params, name) * (1 + (k if name in DRIVE else -k) * error)
                             for name, error in relative_error.items()})


def motor_conditions(description: RobotDescription, references: Mapping[str, ReferenceFit],
                     k: float = 1.0) -> dict[str, RobotDescription]:
    """The robot of ``description`` under each model of ``references`` (``model`` -> its fit), as it is, moved
    ``weaker`` and ``stronger`` by ``k`` standard errors, and (but the appendix) with the reference's load friction:
    ``{"dc_motor weaker": description, ...}``."""
    out = {}
    for model, reference in references.items():
        variants = [("", 0.0, False), *((move, sign, False) for move, sign in zip(MOVES, (-k, k), strict=True))]
        if model != "appendix":
            variants.append(("+ load friction", 0.0, True))
        for variant, sign, load_friction in variants:
            catalogue = description.catalogue
            for name in sorted({m.model for m in description.motors}):
                entry = catalogue[name]
                params = entry.actuator if model == "appendix" else \
                    under_model(entry.actuator, entry.stall_torque_nm, reference, load_friction)
                catalogue = catalogue.with_actuator(name, moved(params, reference.identified, sign))
            out[f"{model} {variant}".strip()] = RobotDescription(description.spec, catalogue,
                                                                 description.motor_params_files)
    return out


def reference_fits(folder: str | Path) -> dict[str, ReferenceFit]:
    """Each of `MODELS`' reference fits, ``<model>.json`` in ``folder``."""
    return {model: ReferenceFit.load(Path(folder) / f"{model}.json") for model in MODELS}
