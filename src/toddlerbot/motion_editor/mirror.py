"""Left/right mirroring of a pose in the motion editor: the robot's joint mirror (`robot.mirror.mirror_partners`,
derived from the joint axes: +1 for most rolls, -1 for pitches, yaws and the centre joints' yaw and roll) with
each mirrored value clamped to its joint's range. The spec's home pose is its own mirror image under this map
(`tests/test_motion_editor.py`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.mirror import mirror_partners

Side = Literal["left", "right"]


@dataclass(frozen=True)
class MirrorMap:
    joint_names: tuple[str, ...]
    partner: np.ndarray
    """(n,) index of each joint's mirror partner."""
    sign: np.ndarray
    """(n,) q_partner = sign * q for a mirrored pose."""
    ranges: np.ndarray
    """(n, 2) joint ranges, rad (mirrored values are clamped to the partner's range)."""

    @classmethod
    def of(cls, description: RobotDescription) -> MirrorMap:
        partner, sign = mirror_partners(description, description.joint_names)
        return cls(tuple(description.joint_names), partner, sign, np.asarray(description.joint_range))

    def side(self, joint: str) -> Side | None:
        return "left" if joint.startswith("left_") else "right" if joint.startswith("right_") else None

    def swapped(self, pose: np.ndarray) -> np.ndarray:
        """The whole pose reflected: left and right exchange, centre yaws and rolls change sign."""
        out = np.empty_like(pose)
        out[self.partner] = self.sign * pose
        return self._clamp(out)

    def copied(self, pose: np.ndarray, source: Side) -> np.ndarray:
        """`source`'s side reflected onto the other side; the source side and the centre are unchanged."""
        out = np.array(pose, dtype=float)
        for i, joint in enumerate(self.joint_names):
            if self.side(joint) == source:
                out[self.partner[i]] = self.sign[i] * pose[i]
        return self._clamp(out)

    def follow(self, pose: np.ndarray, joint: str) -> tuple[str, float] | None:
        """The partner joint and its mirrored value after `joint` was moved (None for a centre joint)."""
        i = self.joint_names.index(joint)
        k = int(self.partner[i])
        if k == i:
            return None
        lo, hi = self.ranges[k]
        return self.joint_names[k], float(np.clip(self.sign[i] * pose[i], lo, hi))

    def _clamp(self, pose: np.ndarray) -> np.ndarray:
        return np.clip(pose, self.ranges[:, 0], self.ranges[:, 1])
