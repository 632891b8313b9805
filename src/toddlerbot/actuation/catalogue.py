"""The Dynamixel motor catalogue: datasheet figures and actuator-model parameters per motor model.

Each model's ``actuator`` entry names its actuator model (``model: appendix``, the default, or ``dc_motor``) and
that model's parameters (`ActuatorParams`, `toddlerbot.actuation.dc_motor.DCMotorParams`); `MOTOR_MODELS` maps
the names to the classes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from typing import ClassVar

import yaml

from toddlerbot.actuation.dc_motor import DCMotorParams
from toddlerbot.actuation.motor_params import MotorParams, check_fields
from toddlerbot.errors import SpecError
from toddlerbot.yaml_input import read_yaml

DEFAULT_CATALOGUE = resources.files("toddlerbot.actuation") / "motors.yaml"
ACTUATOR_MAX = {"damping": 10.0, "armature": 1.0, "frictionloss": 100.0, "tau_max": 1000.0, "q_dot_tau_max": 1000.0,
                "q_dot_max": 1000.0, "tau_q_dot_max": 1000.0, "kd_min": 100.0, "tau_brake": 1000.0,
                "kp_scale": 1e5, "stiction": 100.0, "stribeck_velocity": 1000.0, "load_friction": 1.0}
"""Plausible upper bound of each actuator parameter (units as in `ActuatorParams`): finite is not enough (tau_max
1e300 is finite); each lies orders of magnitude above the system-ID search bounds and any Dynamixel's figure."""
MOTOR_RANGES = {"stall_torque_nm": (1e-3, 1000.0), "mass_kg": (1e-3, 100.0), "rated_voltage": (1.0, 100.0)}
"""Plausible (low, high) of a motor model's datasheet figures, N*m, kg, V."""


@dataclass(frozen=True)
class ActuatorParams:
    """Parameters of the appendix's actuator model (Eq. 8-10), in joint units of the motor's output shaft."""

    model: ClassVar[str] = "appendix"

    damping: float
    """Passive viscous resistance, N*m*s/rad."""
    armature: float
    """Reflected rotor inertia, kg*m^2."""
    frictionloss: float
    """Coulomb friction, N*m."""
    tau_max: float
    """Acceleration torque limit at low speed, N*m."""
    q_dot_tau_max: float
    """Speed up to which tau_max is available, rad/s."""
    q_dot_max: float
    """Speed at which the acceleration limit has fallen to tau_q_dot_max, rad/s."""
    tau_q_dot_max: float
    """Acceleration torque limit at q_dot_max and beyond, N*m."""
    kd_min: float
    """Damping added by the powered motor's controller, N*m*s/rad."""
    tau_brake: float
    """Braking torque limit, N*m."""
    kp_scale: float
    """Dynamixel position P gain divided by the physical stiffness in N*m/rad."""
    stiction: float = 0.0
    """Extended model: static friction in excess of the Coulomb ``frictionloss`` at zero speed, N*m (0: none)."""
    stribeck_velocity: float = 0.1
    """Extended model: speed over which the excess static friction decays (exp(-(q_dot/v)^2)), rad/s."""
    load_friction: float = 0.0
    """Extended model: Coulomb friction per N*m of transmitted motor torque (1 - efficiency), 1 (0: none)."""

    def __post_init__(self) -> None:
        check_fields(self, ACTUATOR_MAX)
        if self.q_dot_max <= self.q_dot_tau_max:
            raise ValueError(f"q_dot_max ({self.q_dot_max}) must exceed q_dot_tau_max ({self.q_dot_tau_max})")
        if self.kp_scale <= 0:
            raise ValueError(f"kp_scale must be > 0, got {self.kp_scale}")
        if self.stribeck_velocity <= 0:
            raise ValueError(f"stribeck_velocity must be > 0, got {self.stribeck_velocity}")
        if self.load_friction >= 1:
            raise ValueError(f"load_friction must be < 1 (share of the transmitted torque), got {self.load_friction}")

    def replace(self, **changes: float) -> ActuatorParams:
        return dataclasses.replace(self, **changes)

    def array_fields(self, kp_dynamixel: float, kd_dynamixel: float) -> dict[str, float]:
        """This motor's `toddlerbot.actuation.model.ActuatorArrays` entries at these firmware gains."""
        return self.fields_to_arrays(dataclasses.asdict(self), kp_dynamixel, kd_dynamixel)

    @staticmethod
    def fields_to_arrays(f: Mapping, kp_dynamixel, kd_dynamixel) -> dict:
        """`ActuatorArrays` entries from field values (floats, or arrays of candidates in a fit; constants stay
        scalars and broadcast): physical gains from kp_scale, no back-EMF after the limit, a linear PWM."""
        same = ("kd_min", "tau_max", "q_dot_tau_max", "q_dot_max", "tau_q_dot_max", "tau_brake", "stiction",
                "stribeck_velocity", "load_friction")
        return {**{name: f[name] for name in same}, "kp": kp_dynamixel / f["kp_scale"],
                "kd": kd_dynamixel / f["kp_scale"], "back_emf_damping": 0.0, "pwm_exponent": 1.0}


MOTOR_MODELS: dict[str, type[ActuatorParams] | type[DCMotorParams]] = {
    ActuatorParams.model: ActuatorParams, DCMotorParams.model: DCMotorParams,
}
"""Actuator models by the name a catalogue entry or params.json gives in ``model``."""


def motor_params(fields: Mapping, source: str) -> MotorParams:
    """Parameters from a mapping of field values with an optional ``model`` name (default ``appendix``);
    raise ValueError naming an unknown model, a missing or an unknown field."""
    fields = dict(fields)
    name = fields.pop("model", ActuatorParams.model)
    if not isinstance(name, str) or name not in MOTOR_MODELS:
        raise ValueError(f"{source}: unknown actuator model {name!r}; expected one of {', '.join(MOTOR_MODELS)}")
    cls = MOTOR_MODELS[name]
    known = [f.name for f in dataclasses.fields(cls)]
    missing = [f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING and f.name not in fields]
    if missing:
        raise ValueError(f"{source}: the {name} model needs {', '.join(missing)}")
    unknown = sorted(set(fields) - set(known))
    if unknown:
        raise ValueError(f"{source}: unknown {name} field(s) {', '.join(unknown)}; expected {', '.join(known)}")
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
