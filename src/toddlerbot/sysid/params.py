"""The fitted actuator parameters: search bounds, candidate matrices and ``params.json`` files.

A ``params.json`` (written by ``toddlerbot sysid fit``) holds ``{"motor": <catalogue name>, "actuator": {every
ActuatorParams field, including the extended model's}, "fitted": [names], "fit": {...provenance...}}``.
`toddlerbot.actuation.params_file.catalogue_with_params` loads them into a motor `Catalogue` (and
``RobotDescription.load(motor_params=...)`` into a robot).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from toddlerbot.actuation.catalogue import ActuatorParams
from toddlerbot.files import atomic_write_text
from toddlerbot.sysid.errors import SysIDError

MODEL_PARAMETERS = (
    "damping", "frictionloss", "armature", "tau_max", "q_dot_tau_max", "tau_q_dot_max", "q_dot_max", "kd_min",
    "tau_brake",
)
"""The 9 parameters of the appendix (section 8.9), always fitted."""
EXTENDED_PARAMETERS = ("stiction", "stribeck_velocity", "load_friction")
"""Fitted in addition with ``model="extended"`` (see `toddlerbot.actuation.model.extra_friction`)."""
MODELS = ("appendix", "extended")
BOUND_MARGIN = 0.01
"""A fitted parameter within this share of its searched range (the unit cube, log-scaled where the search is) of
a bound is reported as at that bound."""

BOUNDS: dict[str, tuple[float, float]] = {
    "damping": (1e-4, 0.05),  # N*m*s/rad
    "frictionloss": (1e-3, 0.3),  # N*m
    "armature": (2e-4, 0.03),  # kg*m^2
    "tau_max": (0.05, 6.0),  # N*m
    "q_dot_tau_max": (0.0, 8.0),  # rad/s
    "tau_q_dot_max": (0.0, 1.0),  # FRACTION of tau_max (the limit falls with speed)
    "q_dot_max": (0.2, 20.0),  # rad/s ABOVE q_dot_tau_max (searched as the span, so q_dot_max > q_dot_tau_max)
    "kd_min": (0.01, 2.0),  # N*m*s/rad
    "tau_brake": (0.05, 10.0),  # N*m
    "kp_scale": (15.0, 1000.0),  # firmware P gain per N*m/rad: 173.8 / stall torque over the X series (motors.yaml)
    "stiction": (1e-4, 0.3),  # N*m above frictionloss
    "stribeck_velocity": (0.01, 3.0),  # rad/s
    "load_friction": (0.0, 0.6),  # 1 (share of the transmitted torque)
}
"""Search bounds of each parameter (q_dot_max: bounds of q_dot_max - q_dot_tau_max; tau_q_dot_max: bounds of
tau_q_dot_max / tau_max)."""

SEARCHED_AS = {"q_dot_max": " above q_dot_tau_max", "tau_q_dot_max": " x tau_max"}
"""How the bounds of the parameters not searched directly apply."""

LOG_SCALED = frozenset({"damping", "frictionloss", "armature", "tau_max", "kd_min", "tau_brake", "kp_scale",
                        "stiction", "stribeck_velocity"})
"""Parameters searched on a log scale (positive, spanning one to three decades); the speeds and the torque
fraction are searched linearly."""


def parameter_names(fit_kp_scale: bool, model: str = "appendix") -> tuple[str, ...]:
    """The fitted parameters of ``model`` (``appendix``: the 9 of section 8.9; ``extended``: plus stiction,
    Stribeck velocity and load friction), plus kp_scale if asked."""
    if model not in MODELS:
        raise SysIDError(f"unknown model {model!r}; expected one of {', '.join(MODELS)}")
    names = MODEL_PARAMETERS + (EXTENDED_PARAMETERS if model == "extended" else ())
    return (*names, "kp_scale") if fit_kp_scale else names


def at_bounds(u: np.ndarray, names: Sequence[str]) -> dict[str, str]:
    """Parameters of a unit-cube point within `BOUND_MARGIN` of a bound: name -> ``"lower"`` / ``"upper"``
    (for q_dot_max and tau_q_dot_max the bound is on the searched span / fraction, see `BOUNDS`)."""
    out = {}
    for name, x in zip(names, np.asarray(u, dtype=float), strict=True):
        if x <= BOUND_MARGIN:
            out[name] = "lower"
        elif x >= 1.0 - BOUND_MARGIN:
            out[name] = "upper"
    return out


def _searched(name: str, params: ActuatorParams) -> float:
    """The value the optimiser sees for ``name`` (span for q_dot_max, fraction of tau_max for tau_q_dot_max)."""
    if name == "q_dot_max":
        return params.q_dot_max - params.q_dot_tau_max
    if name == "tau_q_dot_max":
        return params.tau_q_dot_max / params.tau_max
    return getattr(params, name)


def to_unit(params: ActuatorParams, names: Sequence[str]) -> np.ndarray:
    """Parameters -> point of the unit cube the optimiser searches (clipped into the bounds)."""
    u = []
    for name in names:
        lo, hi = BOUNDS[name]
        value = min(max(_searched(name, params), lo), hi)
        u.append(np.log(value / lo) / np.log(hi / lo) if name in LOG_SCALED else (value - lo) / (hi - lo))
    return np.clip(np.array(u), 0.0, 1.0)


def from_unit(u: np.ndarray, names: Sequence[str], base: ActuatorParams) -> dict[str, np.ndarray]:
    """Unit-cube points (pop, len(names)) -> every ActuatorParams field as an array (pop,); unfitted fields
    keep ``base``'s value."""
    u = np.atleast_2d(np.clip(u, 0.0, 1.0))
    out = {f.name: np.full(len(u), float(getattr(base, f.name))) for f in dataclasses.fields(ActuatorParams)}
    for i, name in enumerate(names):
        lo, hi = BOUNDS[name]
        out[name] = lo * (hi / lo) ** u[:, i] if name in LOG_SCALED else lo + u[:, i] * (hi - lo)
    if "q_dot_max" in names:
        out["q_dot_max"] = out["q_dot_max"] + out["q_dot_tau_max"]
    if "tau_q_dot_max" in names:
        out["tau_q_dot_max"] = out["tau_q_dot_max"] * out["tau_max"]
    return out


def params_at(fields: dict[str, np.ndarray], i: int) -> ActuatorParams:
    """Candidate ``i`` of `from_unit`'s output as ActuatorParams."""
    return ActuatorParams(**{k: float(v[i]) for k, v in fields.items()})


def save_params(path: str | Path, motor: str, params: ActuatorParams, fitted: Iterable[str],
                fit: dict[str, Any]) -> Path:
    """Write a params.json atomically (a failed or interrupted write leaves any previous file untouched)."""
    body = {"motor": motor, "actuator": dataclasses.asdict(params), "fitted": list(fitted), "fit": fit}
    return atomic_write_text(path, json.dumps(body, indent=2) + "\n")
