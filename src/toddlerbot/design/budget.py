"""Weight estimate and power budget (appendix sections 8.5 and 8.6); every input is a parameter."""

from __future__ import annotations

from dataclasses import dataclass

from toddlerbot.robot.description import RobotDescription


@dataclass(frozen=True)
class WeightInputs:
    """Appendix 8.5: 3100 g = 30 x 50 g (motors) + 600 g (computer, battery, camera) + 1000 g (structure)."""

    motor_mass_kg: float = 0.050
    """Assumed mass of the smallest Dynamixel units, per motor."""
    electronics_mass_kg: float = 0.600
    structure_mass_kg: float = 1.000
    """3D-printed parts and metal hardware."""


@dataclass(frozen=True)
class WeightEstimate:
    motors: int
    estimate_kg: float
    catalogue_motor_mass_kg: float
    """Motor mass from the catalogue (a dual-axis unit counted once)."""
    spec_mass_kg: float

    @property
    def error_fraction(self) -> float:
        return (self.estimate_kg - self.spec_mass_kg) / self.spec_mass_kg


def weight_estimate(description: RobotDescription, inputs: WeightInputs = WeightInputs()) -> WeightEstimate:
    n = description.n_motors
    return WeightEstimate(
        motors=n,
        estimate_kg=n * inputs.motor_mass_kg + inputs.electronics_mass_kg + inputs.structure_mass_kg,
        catalogue_motor_mass_kg=sum(model.mass_per_axis_kg for model in description.motor_models),
        spec_mass_kg=description.spec.total_mass,
    )


@dataclass(frozen=True)
class PowerInputs:
    """Appendix 8.6 figures as defaults."""

    electronics_w: float = 15.0
    """Computer and camera under typical load."""
    motors_active_w: float = 72.0
    """Motor power while the working leg is loaded; at the duty cycle this gives the appendix's ~50 W."""
    duty_cycle: float = 0.7
    battery_voltage_v: float = 14.8
    """4-cell nominal."""
    battery_capacity_ah: float = 5.0
    """The custom 4-cell 21700 pack (the off-the-shelf LiPo option is 2.0 Ah)."""
    usable_fraction: float = 0.85
    """Depth of discharge used."""
    target_runtime_h: float = 1.0
    battery_peak_current_a: float = 25.0

    def __post_init__(self) -> None:
        for name in ("duty_cycle", "usable_fraction"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in (0, 1], got {getattr(self, name)}")
        for name, high in (("electronics_w", 1e4), ("motors_active_w", 1e5), ("battery_voltage_v", 1000.0),
                           ("battery_capacity_ah", 1000.0), ("target_runtime_h", 1000.0),
                           ("battery_peak_current_a", 1e4)):
            if not 0 < getattr(self, name) <= high:  # False for NaN: no NaN in the budget or its JSON
                raise ValueError(f"{name} must be in (0, {high:g}], got {getattr(self, name)}")


@dataclass(frozen=True)
class PowerBudget:
    electronics_w: float
    motors_w: float
    total_w: float
    battery_wh: float
    runtime_h: float
    battery_wh_for_target: float
    peak_power_w: float


def power_budget(inputs: PowerInputs = PowerInputs()) -> PowerBudget:
    motors = inputs.motors_active_w * inputs.duty_cycle
    total = inputs.electronics_w + motors
    battery = inputs.battery_voltage_v * inputs.battery_capacity_ah
    return PowerBudget(
        electronics_w=inputs.electronics_w,
        motors_w=motors,
        total_w=total,
        battery_wh=battery,
        runtime_h=battery * inputs.usable_fraction / total,
        battery_wh_for_target=total * inputs.target_runtime_h / inputs.usable_fraction,
        peak_power_w=inputs.battery_voltage_v * inputs.battery_peak_current_a,
    )
