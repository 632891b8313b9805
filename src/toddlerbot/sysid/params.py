"""What a fit searches: the fitted models (each registered motor model's fits), the unit cube over the parameters'
fit bounds (from the models' parameter tables, `toddlerbot.actuation.motor_models.all_parameters`), candidate
matrices, ``params.json``.

A ``params.json`` (written by ``toddlerbot sysid fit``) holds ``{"motor": <catalogue name>, "actuator": {"model":
name, every field of that model}, "fitted": [names], "fit": {...provenance, uncertainty...}}``.
`toddlerbot.actuation.params_file.catalogue_with_params` loads them into a motor `Catalogue` (and
``RobotDescription.load(motor_params=...)`` into a robot).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from toddlerbot.actuation.catalogue import params_dict
from toddlerbot.actuation.model import ActuatorArrays
from toddlerbot.actuation.motor_models import all_parameters, fits
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.files import atomic_write_text
from toddlerbot.sysid.errors import SysIDError


class SearchRange(NamedTuple):
    """Where the fit looks for one parameter."""

    low: float
    high: float
    log: bool
    """Searched on a log scale (positive parameters spanning decades), else linearly."""
    unit: str


def search_range(name: str) -> SearchRange:
    """Where the fit looks for parameter ``name``: its fit bounds in its model's table (q_dot_max and
    tau_q_dot_max: of the span / fraction they are searched as, see `searched_as`)."""
    p = all_parameters()[name]
    return SearchRange(p.lower, p.upper, p.log, p.unit)


def searched_as(name: str) -> str:
    """How parameter ``name``'s search range applies: ``" above q_dot_tau_max"``, ``" x tau_max"``, or ``""`` (to
    its value)."""
    p = all_parameters()[name]
    return f" above {p.span_above}" if p.span_above else f" x {p.fraction_of}" if p.fraction_of else ""

BOUND_MARGIN = 0.01
"""A fitted parameter within this share of its searched range (the unit cube, log-scaled where the search is) of
a bound is reported as at that bound."""


@dataclass(frozen=True)
class FitModel:
    """One model `sysid fit --model` can fit: its parameter class and what is fitted, what is not and why (a
    registered motor model's `toddlerbot.actuation.motor_models.Fit`)."""

    name: str
    params_class: type
    fitted: tuple[str, ...]
    """Always fitted, in the CMA-ES vector's order."""
    gain_parameter: str
    """The firmware-to-physical gain conversion, fitted with ``--fit-kp-scale`` (else kept from the start)."""
    fixed: dict[str, str]
    """Parameters of the class the fit leaves as they start, with the reason."""


def fit_models() -> dict[str, FitModel]:
    """What `sysid fit --model` takes: every registered motor model's fits."""
    return {name: FitModel(name, cls, fit.fitted, fit.gain_parameter, dict(fit.fixed))
            for name, (cls, fit) in fits().items()}


DEFAULT_MODEL = "dc_motor"
"""`sysid fit`'s default (docs/sysid.md: the one that holds on real servos)."""


def fit_model(name: str) -> FitModel:
    """The `FitModel` called ``name``; raise `SysIDError` naming the known ones."""
    models = fit_models()
    if name not in models:
        raise SysIDError(f"unknown model {name!r}; expected one of {', '.join(models)}")
    return models[name]


def parameter_names(fit_kp_scale: bool, model: str = DEFAULT_MODEL) -> tuple[str, ...]:
    """The fitted parameters of ``model``, plus its gain conversion if asked."""
    m = fit_model(model)
    return (*m.fitted, m.gain_parameter) if fit_kp_scale else m.fitted


def start_params(model: str, params: MotorParams) -> MotorParams:
    """The start of a ``model`` fit from a motor's parameters (its catalogue entry or ``--start``): the same
    parameters where the model matches, else the same motor in the fitted model's terms (its ``like``)."""
    cls = fit_model(model).params_class
    if isinstance(params, cls):
        return params
    try:
        return cls.like(params)
    except ValueError as exc:
        raise SysIDError(f"--model {model}: {exc}") from None


def at_bounds(u: np.ndarray, names: Sequence[str]) -> dict[str, str]:
    """Parameters of a unit-cube point within `BOUND_MARGIN` of a bound: name -> ``"lower"`` / ``"upper"``
    (for q_dot_max and tau_q_dot_max the bound is on the searched span / fraction, see `searched_value`)."""
    out = {}
    for name, x in zip(names, np.asarray(u, dtype=float), strict=True):
        if x <= BOUND_MARGIN:
            out[name] = "lower"
        elif x >= 1.0 - BOUND_MARGIN:
            out[name] = "upper"
    return out


def searched_value(name: str, params: MotorParams) -> float:
    """The value the optimiser sees for ``name``: its value, or its span or fraction (`ParameterDef.span_above`,
    `ParameterDef.fraction_of`)."""
    p = all_parameters()[name]
    if p.span_above:
        return getattr(params, name) - getattr(params, p.span_above)
    if p.fraction_of:
        return getattr(params, name) / getattr(params, p.fraction_of)
    return getattr(params, name)


def to_unit(params: MotorParams, names: Sequence[str]) -> np.ndarray:
    """Parameters -> point of the unit cube the optimiser searches (clipped into the ranges)."""
    u = []
    for name in names:
        lo, hi, log, _ = search_range(name)
        value = min(max(searched_value(name, params), lo), hi)
        u.append(np.log(value / lo) / np.log(hi / lo) if log else (value - lo) / (hi - lo))
    return np.clip(np.array(u), 0.0, 1.0)


@dataclass(frozen=True)
class Candidates:
    """P parameter sets of one model, field by field: what a fit's generation simulates at once."""

    params_class: type
    fields: dict[str, np.ndarray]
    """Every field of the class, each an array of shape (P,)."""

    @classmethod
    def of(cls, params: MotorParams) -> Candidates:
        """One candidate: ``params``."""
        return cls(type(params), {f.name: np.array([float(getattr(params, f.name))])
                                  for f in dataclasses.fields(params)})

    def __len__(self) -> int:
        return len(next(iter(self.fields.values())))

    def arrays(self, kp_dynamixel: np.ndarray, kd_dynamixel: np.ndarray) -> ActuatorArrays:
        """Actuator arrays of shape (P, R) for runs at firmware gains ``kp_dynamixel``, ``kd_dynamixel`` (R,)."""
        column = {k: np.asarray(v, dtype=float)[:, None] for k, v in self.fields.items()}
        return ActuatorArrays(**self.params_class.fields_to_arrays(
            column, np.asarray(kp_dynamixel)[None, :], np.asarray(kd_dynamixel)[None, :]))

    def params(self, i: int) -> MotorParams:
        """Candidate ``i`` as parameters (validated)."""
        return self.params_class(**{k: float(v[i]) for k, v in self.fields.items()})


def from_unit(u: np.ndarray, names: Sequence[str], base: MotorParams) -> Candidates:
    """Unit-cube points (pop, len(names)) -> candidates of ``base``'s model; unfitted fields keep ``base``'s
    value."""
    u = np.atleast_2d(np.clip(u, 0.0, 1.0))
    out = {f.name: np.full(len(u), float(getattr(base, f.name))) for f in dataclasses.fields(base)}
    for i, name in enumerate(names):
        lo, hi, log, _ = search_range(name)
        out[name] = lo * (hi / lo) ** u[:, i] if log else lo + u[:, i] * (hi - lo)
    for name in names:  # spans and fractions back to values, once every searched value is in
        p = all_parameters()[name]
        if p.span_above:
            out[name] = out[name] + out[p.span_above]
        elif p.fraction_of:
            out[name] = out[name] * out[p.fraction_of]
    return Candidates(type(base), out)


def save_params(path: str | Path, motor: str, params: MotorParams, fitted: Iterable[str],
                fit: dict[str, Any]) -> Path:
    """Write a params.json atomically (a failed or interrupted write leaves any previous file untouched)."""
    body = {"motor": motor, "actuator": params_dict(params), "fitted": list(fitted), "fit": fit}
    return atomic_write_text(path, json.dumps(body, indent=2) + "\n")
