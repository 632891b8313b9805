"""Joint torque requirement scaled from human reference torques (appendix Eq. 5).

tau_robot = (h_robot * m_robot) / (h_human * m_human) * tau_human
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.design.data import load
from toddlerbot.robot.description import RobotDescription


@dataclass(frozen=True)
class JointCheck:
    joint: str
    required_nm: float
    available_nm: float
    """Stall torque at the joint through its transmission, N*m."""

    @property
    def sufficient(self) -> bool:
        return bool(self.available_nm >= self.required_nm)


def human_reference() -> dict:
    return load("human_torque")


def required_torques(height_m: float, mass_kg: float) -> dict[str, float]:
    """Eq. 5 for every joint of the human reference, N*m."""
    human = human_reference()
    scale = (height_m * mass_kg) / (human["height_m"] * human["mass_kg"])
    return {joint: scale * tau for joint, tau in human["peak_torque_nm"].items()}


def check_joints(description: RobotDescription, height_m: float, mass_kg: float) -> list[JointCheck]:
    """Compare each required torque with the stall torque available at every robot joint of that kind.

    A joint of kind ``knee`` is every output joint named ``*knee`` (left and right). The torque available at a
    joint is the smallest stall torque / |transmission coefficient| over the motors that drive it.
    """
    tmap = description.transmission
    stall = np.array([model.stall_torque_nm for model in description.motor_models])
    checks = []
    for kind, required in required_torques(height_m, mass_kg).items():
        for row, joint in zip(tmap.matrix, tmap.joint_names):
            if joint.removeprefix("left_").removeprefix("right_") != kind:
                continue
            drivers = np.flatnonzero(row)
            available = float(np.min(stall[drivers] / np.abs(row[drivers])))
            checks.append(JointCheck(joint, required, available))
    return checks
