"""The design report: every metric of the appendix's design sections in one object, printable and JSON-able."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from toddlerbot.design.budget import (
    PowerBudget,
    PowerInputs,
    WeightEstimate,
    WeightInputs,
    power_budget,
    weight_estimate,
)
from toddlerbot.design.power_factor import Humanoid, PowerFactor, reference_humanoids, robot_power_factor
from toddlerbot.design.range_of_motion import RangeRow, range_of_motion
from toddlerbot.design.torque_requirement import JointCheck, check_joints, human_reference, required_torques
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.summary import standing_height

REQUIREMENT_JOINTS = ("knee", "ankle_pitch", "hip_pitch")


@dataclass(frozen=True)
class DesignReport:
    robot: str
    height_m: float
    mass_kg: float
    active_dof: int
    power_factor: PowerFactor
    humanoids: list[Humanoid]
    torque_requirement_nm: dict[str, float]
    joint_checks: list[JointCheck]
    weight: WeightEstimate
    power: PowerBudget
    range_of_motion: list[RangeRow]

    @property
    def insufficient_joints(self) -> list[JointCheck]:
        return [c for c in self.joint_checks if not c.sufficient]

    def to_json(self) -> dict:
        return {
            "robot": self.robot,
            "height_m": self.height_m,
            "mass_kg": self.mass_kg,
            "active_dof": self.active_dof,
            "power_factor": {"total": self.power_factor.total, "upper": self.power_factor.upper,
                             "lower": self.power_factor.lower, "sum_torque_nm": self.power_factor.sum_torque_nm},
            "torque_requirement_nm": {k: self.torque_requirement_nm[k] for k in REQUIREMENT_JOINTS},
            "joint_checks": [asdict(c) | {"sufficient": c.sufficient} for c in self.joint_checks],
            "insufficient_joints": [c.joint for c in self.insufficient_joints],
            "human_reference": human_reference(),
            "humanoids": [asdict(h) | {"power_factor": h.power_factor} for h in self.humanoids],
            "weight": asdict(self.weight) | {"error_fraction": self.weight.error_fraction},
            "power_budget": asdict(self.power),
            "range_of_motion": [
                {"joint": r.joint, "robot_deg": list(r.robot_deg), "robot_span_deg": r.robot_span_deg,
                 "human_joint": r.human_joint, "human_deg": list(r.human_deg) if r.human_deg else None,
                 "human_span_deg": r.human_span_deg}
                for r in self.range_of_motion
            ],
        }


HEIGHT_RANGE_M = (0.1, 2.5)
"""Heights the design metrics accept, m: from a hand-sized robot to beyond a tall adult (what-if designs of 1.8 m)."""
MASS_RANGE_KG = (0.05, 300.0)
"""Masses the design metrics accept, kg."""


def design_report(
    description: RobotDescription,
    height_m: float | None = None,
    mass_kg: float | None = None,
    weight_inputs: WeightInputs = WeightInputs(),
    power_inputs: PowerInputs = PowerInputs(),
) -> DesignReport:
    """All design metrics from the description's spec and motor catalogue; height and mass default to the robot's
    (standing height of its floating-base model, total mass of the spec)."""
    spec = description.spec
    height = float(height_m if height_m is not None else standing_height(description.model("floating", scene=False)))
    mass = float(mass_kg if mass_kg is not None else spec.total_mass)
    if not (HEIGHT_RANGE_M[0] <= height <= HEIGHT_RANGE_M[1] and MASS_RANGE_KG[0] <= mass <= MASS_RANGE_KG[1]):
        raise ValueError(f"height {height} m and mass {mass} kg: expected {HEIGHT_RANGE_M} m and {MASS_RANGE_KG} kg")
    return DesignReport(
        robot=spec.name if spec.variant is None else f"{spec.name} ({spec.variant})",
        height_m=height,
        mass_kg=mass,
        active_dof=description.n_motors,
        power_factor=robot_power_factor(description, height, mass),
        humanoids=reference_humanoids(),
        torque_requirement_nm=required_torques(height, mass),
        joint_checks=check_joints(description, height, mass),
        weight=weight_estimate(description, weight_inputs),
        power=power_budget(power_inputs),
        range_of_motion=range_of_motion(description),
    )
