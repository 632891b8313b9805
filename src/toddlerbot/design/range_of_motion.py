"""Range of motion of every joint next to typical human values (appendix Figure 6)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from toddlerbot.design.data import load
from toddlerbot.robot.description import RobotDescription

# Human joint (data/human_rom.yaml key) compared with each robot output joint (side prefix removed).
HUMAN_JOINT = {
    "neck_yaw": "neck_yaw", "neck_pitch": "neck_pitch", "waist_yaw": "waist_yaw", "waist_roll": "waist_roll",
    "shoulder_pitch": "shoulder_pitch", "shoulder_roll": "shoulder_roll", "shoulder_yaw": "shoulder_yaw",
    "elbow_roll": "elbow_pitch", "elbow_yaw": "forearm_roll", "wrist_pitch": "wrist_pitch",
    "hip_pitch": "hip_pitch", "hip_roll": "hip_roll", "hip_yaw": "hip_yaw", "knee": "knee_pitch",
    "ankle_pitch": "ankle_pitch", "ankle_roll": "ankle_roll",
}


@dataclass(frozen=True)
class RangeRow:
    joint: str
    robot_deg: tuple[float, float]
    """Joint limits in the robot's own joint frame, degrees."""
    human_joint: str | None
    human_deg: tuple[float, float] | None
    """Typical human range, appendix sign convention (negative = extension/adduction/inversion), degrees."""

    @property
    def robot_span_deg(self) -> float:
        return self.robot_deg[1] - self.robot_deg[0]

    @property
    def human_span_deg(self) -> float | None:
        return None if self.human_deg is None else self.human_deg[1] - self.human_deg[0]


def range_of_motion(description: RobotDescription) -> list[RangeRow]:
    """One row per output joint of the left side and the midline (the right side mirrors the left)."""
    human = load("human_rom")["joints"]
    joints = description.spec.joints
    rows = []
    for name in description.joint_names:
        if name.startswith("right_") or joints[name].range is None or joints[name].type != "hinge":
            continue
        key = HUMAN_JOINT.get(name.removeprefix("left_"))
        lo, hi = (math.degrees(x) for x in joints[name].range)
        ref = (float(human[key]["min"]), float(human[key]["max"])) if key else None
        rows.append(RangeRow(name, (lo, hi), key, ref))
    return rows
