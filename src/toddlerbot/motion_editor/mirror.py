"""Left/right mirroring of a pose, derived from the model's joint axes (no table of signs to keep in step).

Reflecting the robot in its sagittal plane (y -> -y, M = diag(1, -1, 1)) turns a rotation by q about axis a into
a rotation by q about -M a. A joint's partner (``left_*`` <-> ``right_*``; a centre joint is its own partner)
has axis b, so the mirrored angle is q' = s q with s = -b . (M a): +1 for most rolls, -1 for pitches, yaws and
the centre joints' yaw and roll. Axes are read in the world frame at the model's zero pose, where the robot is
symmetric. The spec's home pose is its own mirror image under this map (`tests/test_motion_editor.py`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from toddlerbot.robot.description import RobotDescription

Side = Literal["left", "right"]
_REFLECT = np.diag([1.0, -1.0, 1.0])


def partner_name(joint: str) -> str:
    for a, b in (("left_", "right_"), ("right_", "left_")):
        if joint.startswith(a):
            return b + joint.removeprefix(a)
    return joint


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
        model = description.model("floating", scene=True)
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)  # qpos0: the zero pose
        names = description.joint_names
        partner = np.array([names.index(partner_name(j)) for j in names])
        axes = np.array([data.xaxis[model.joint(j).id] for j in names])
        sign = -np.einsum("ij,ij->i", axes[partner], axes @ _REFLECT.T)
        return cls(tuple(names), partner, np.round(sign), np.asarray(description.joint_range))

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
