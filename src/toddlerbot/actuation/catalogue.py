"""The Dynamixel motor catalogue: datasheet figures and actuator-model parameters per motor model.

Each model's ``actuator`` entry names its actuator model (``model: appendix``, the default, ``dc_motor`` or any other
of `toddlerbot.actuation.motor_models.MOTOR_MODELS`) and that model's parameters.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path

import yaml

from toddlerbot.actuation.motor_models import DEFAULT_MOTOR_MODEL, MOTOR_MODELS, motor_model
from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.errors import SpecError
from toddlerbot.yaml_input import read_yaml

DEFAULT_CATALOGUE = resources.files("toddlerbot.actuation") / "motors.yaml"
MOTOR_RANGES = {"stall_torque_nm": (1e-3, 1000.0), "mass_kg": (1e-3, 100.0), "rated_voltage": (1.0, 100.0)}
"""Plausible (low, high) of a motor model's datasheet figures, N*m, kg, V."""


def motor_params(fields: Mapping, source: str) -> MotorParams:
    """Parameters from a mapping of field values with an optional ``model`` name (default ``appendix``);
    raise ValueError naming an unknown model, a missing or an unknown field."""
    fields = dict(fields)
    name = fields.pop("model", DEFAULT_MOTOR_MODEL)
    if not isinstance(name, str) or name not in MOTOR_MODELS:
        raise ValueError(f"{source}: unknown actuator model {name!r}; expected one of "
                         f"{', '.join(MOTOR_MODELS.names())}")
    cls = motor_model(name)
    known = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(fields) - set(known))
    if unknown:  # first: a misspelt field is also a missing one
        raise ValueError(f"{source}: unknown {name} field(s) {', '.join(unknown)}; expected {', '.join(known)}")
    missing = [f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING and f.name not in fields]
    if missing:
        raise ValueError(f"{source}: the {name} model needs {', '.join(missing)}")
    return cls(**fields)


def params_dict(params: MotorParams) -> dict[str, float | str]:
    """``{"model": name, field: value, ...}``: what `motor_params` reads back."""
    return {"model": params.model, **dataclasses.asdict(params)}


@dataclass(frozen=True)
class MotorModel:
    """One Dynamixel model as the robot uses it."""

    name: str
    aliases: tuple[str, ...]
    stall_torque_nm: float
    """Stall torque at ``rated_voltage``, N*m (appendix Table 2 for the robot's motors)."""
    mass_kg: float
    """Mass of one unit, kg (a dual-axis unit drives two motor entries)."""
    dimensions_mm: tuple[float, float, float]
    axes: int
    """Output shafts per unit: 2 for 2XL430 and 2XC430."""
    actuator: MotorParams
    model_number: int | None = None
    """Model number reported by a Dynamixel ping (control table address 0); None if unknown."""
    rated_voltage: float = 12.0
    """Supply voltage, V, at which ``stall_torque_nm`` and the actuator parameters hold (see
    `toddlerbot.actuation.model.at_voltage` for other supplies)."""

    @property
    def mass_per_axis_kg(self) -> float:
        return self.mass_kg / self.axes


class Catalogue:
    """Motor models by name or alias."""

    def __init__(self, models: dict[str, MotorModel], source: str) -> None:
        self.models = models
        self.source = source
        self._by_alias = {alias: m for m in models.values() for alias in (m.name, *m.aliases)}

    def __contains__(self, name: str) -> bool:
        return name in self._by_alias

    def __getitem__(self, name: str) -> MotorModel:
        try:
            return self._by_alias[name]
        except KeyError:
            known = ", ".join(sorted(self._by_alias))
            raise SpecError(f"{self.source}: unknown motor model {name!r}; expected one of: {known}") from None

    def with_actuator(self, name: str, params: MotorParams) -> Catalogue:
        """A copy in which one model uses new actuator parameters (e.g. the output of a system-ID fit)."""
        model = dataclasses.replace(self[name], actuator=params)
        return Catalogue({**self.models, model.name: model}, self.source)


def _parse(raw: object, source: str) -> Catalogue:
    if not isinstance(raw, dict) or not raw:
        raise SpecError(f"{source}: expected a mapping of motor model name -> figures")
    models = {}
    for name, entry in raw.items():
        where = f"{source}: motor model {name!r}"
        try:
            models[name] = MotorModel(
                name=name,
                aliases=tuple(entry.get("aliases", ())),
                stall_torque_nm=float(entry["stall_torque_nm"]),
                mass_kg=float(entry["mass_kg"]),
                dimensions_mm=tuple(float(x) for x in entry["dimensions_mm"]),
                axes=int(entry.get("axes", 1)),
                actuator=motor_params(entry["actuator"], "actuator"),
                model_number=int(entry["model_number"]) if "model_number" in entry else None,
                rated_voltage=float(entry.get("rated_voltage", 12.0)),
            )
            for figure, (low, high) in MOTOR_RANGES.items():
                if not low <= getattr(models[name], figure) <= high:  # False for NaN
                    raise ValueError(f"{figure} must lie in [{low:g}, {high:g}], got {getattr(models[name], figure)}")
        except KeyError as exc:
            raise SpecError(f"{where}: missing field {exc.args[0]!r}") from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise SpecError(f"{where}: {exc}") from None
    return Catalogue(models, source)


def load_catalogue(path: str | Path | None = None) -> Catalogue:
    """Load a motor catalogue (the packaged one by default)."""
    if path is None:
        return default_catalogue()
    path = Path(path)
    return _parse(read_yaml(path, "motor catalogue", SpecError), str(path))


@cache
def default_catalogue() -> Catalogue:
    return _parse(yaml.safe_load(DEFAULT_CATALOGUE.read_text()), "motors.yaml")
