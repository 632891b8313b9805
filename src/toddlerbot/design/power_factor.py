"""Power factor p = sum|tau_max| / (h * m * g) (appendix Eq. 4), split into upper and lower body."""

from __future__ import annotations

from dataclasses import dataclass

from toddlerbot.design.data import load
from toddlerbot.robot.description import RobotDescription

GRAVITY = 9.81
LOWER_BODY_GROUPS = frozenset({"leg"})


@dataclass(frozen=True)
class PowerFactor:
    total: float
    upper: float
    lower: float
    sum_torque_nm: float
    """Sum of the motors' stall torques at 12 V, N*m."""


@dataclass(frozen=True)
class Humanoid:
    name: str
    height_m: float
    mass_kg: float
    active_dof: int
    sum_peak_torque_nm: float
    source: str
    estimated: bool

    @property
    def power_factor(self) -> float:
        return power_factor_of(self.sum_peak_torque_nm, self.height_m, self.mass_kg)


def power_factor_of(sum_torque_nm: float, height_m: float, mass_kg: float) -> float:
    if height_m <= 0 or mass_kg <= 0:
        raise ValueError(f"height and mass must be positive, got h={height_m} m, m={mass_kg} kg")
    return sum_torque_nm / (height_m * mass_kg * GRAVITY)


def robot_power_factor(description: RobotDescription, height_m: float, mass_kg: float) -> PowerFactor:
    """Power factor of a robot from its motors' stall torques (catalogue of the description); lower body = motors of
    the leg group."""
    torque = [model.stall_torque_nm for model in description.motor_models]
    lower = sum(torque[i] for group in LOWER_BODY_GROUPS for i in description.groups.get(group, ()))
    total = sum(torque)
    return PowerFactor(
        total=power_factor_of(total, height_m, mass_kg),
        upper=power_factor_of(total - lower, height_m, mass_kg),
        lower=power_factor_of(lower, height_m, mass_kg),
        sum_torque_nm=total,
    )


def reference_humanoids() -> list[Humanoid]:
    """Other humanoids from public specifications (data/humanoids.yaml, with sources)."""
    return [
        Humanoid(r["name"], r["height_m"], r["mass_kg"], r["active_dof"], r["sum_peak_torque_nm"],
                 " ".join(r["source"].split()), bool(r.get("estimated", False)))
        for r in load("humanoids")["robots"]
    ]
