"""The torso's true pose in a MuJoCo simulation of the floating robot: what the `GroundTruth` backends
(`toddlerbot.sim.mujoco_robot.MuJoCoRobot`, `toddlerbot.hardware.plant.HilPlant`) report, computed here once.

Height and uprightness are read from the torso body's frame as the last ``mj_step`` left it (computed before its
integration); position and orientation from the free joint's state after it. The height is above the ground under the
torso (`toddlerbot.sim.terrain.Ground`: on a terrain, the height field's surface there; on the flat floor, z itself).
"""

from __future__ import annotations

import mujoco
import numpy as np

from toddlerbot.robot.builder import FREEJOINT
from toddlerbot.robot.interface import GroundTruth
from toddlerbot.sim.terrain import Ground

FALL_HEIGHT_FRACTION = 0.6
"""Torso height above the ground below this fraction of its standing height counts as a fall."""


class TorsoTruth:
    """The torso body ``torso`` (the description's handle) of ``data``, a MuJoCo model of the floating robot."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, torso: str) -> None:
        self._data = data
        self._body = model.body(torso).id
        self._base = model.joint(FREEJOINT).qposadr[0]
        self._ground = Ground.of(model)

    def height_and_uprightness(self) -> tuple[float, float]:
        """(height of the torso frame above the ground under it, m; z component of its up axis in the world, 1 =
        upright)."""
        x, y, z = self._data.xpos[self._body]
        if self._ground is not None:
            z = z - self._ground.height(x, y)
        return float(z), float(self._data.xmat[self._body, 8])

    def fallen(self, standing_height: float, fall_tilt_rad: float, height_fraction: float) -> bool:
        """Tilted beyond ``fall_tilt_rad`` from upright or lower than ``height_fraction`` x ``standing_height``."""
        height, uprightness = self.height_and_uprightness()
        return bool(uprightness < np.cos(fall_tilt_rad) or height < height_fraction * standing_height)

    def base_pos(self) -> np.ndarray:
        """Torso position in the world, m (the free joint's)."""
        return self._data.qpos[self._base : self._base + 3].copy()

    def base_quat(self) -> np.ndarray:
        """Torso orientation in the world, quaternion w, x, y, z (the free joint's)."""
        return self._data.qpos[self._base + 3 : self._base + 7].copy()

    def planar_pose(self) -> tuple[np.ndarray, float]:
        """Torso frame (x, y) position, m, and heading (yaw of its x axis), rad."""
        xmat = self._data.xmat[self._body]
        return self._data.xpos[self._body, :2].copy(), float(np.arctan2(xmat[3], xmat[0]))


class TorsoGroundTruth(GroundTruth):
    """`GroundTruth` read from a `TorsoTruth` (``self.torso_truth``), for every backend simulating the floating robot
    in MuJoCo; each keeps its own `fallen` (its thresholds)."""

    torso_truth: TorsoTruth

    @property
    def base_pos(self) -> np.ndarray:
        return self.torso_truth.base_pos()

    @property
    def base_quat(self) -> np.ndarray:
        return self.torso_truth.base_quat()

    def torso_height(self) -> float:
        return self.torso_truth.height_and_uprightness()[0]

    def torso_uprightness(self) -> float:
        return self.torso_truth.height_and_uprightness()[1]
