"""What a simulated chain may sense beyond the `Robot` interface: scene geometry and contacts (sim only)."""

from __future__ import annotations

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.sim.scenes import finger_pads


class SceneProbe:
    """Reads a MuJoCo scene's state; `mark` records the body positions that displacements are measured from."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.model, self.data = model, data
        self._start = data.xpos.copy()

    def mark(self) -> None:
        self._start = self.data.xpos.copy()

    def _id(self, kind: mujoco.mjtObj, name: str) -> int:
        i = mujoco.mj_name2id(self.model, kind, name)
        if i < 0:
            what = "geom" if kind == mujoco.mjtObj.mjOBJ_GEOM else "body"
            raise ToddlerbotError(f"the scene has no {what} named {name!r}")
        return i

    def geom_pos(self, name: str) -> np.ndarray:
        """World position of a geom's centre, m."""
        return self.data.geom_xpos[self._id(mujoco.mjtObj.mjOBJ_GEOM, name)].copy()

    def displacement(self, body: str) -> float:
        """Horizontal distance a body moved since `mark`, m."""
        i = self._id(mujoco.mjtObj.mjOBJ_BODY, body)
        return float(np.linalg.norm(self.data.xpos[i, :2] - self._start[i, :2]))

    def pinching(self, side: str, geom: str) -> bool:
        """Do both finger pads of the `side` gripper touch `geom`?"""
        target = self._id(mujoco.mjtObj.mjOBJ_GEOM, geom)
        pads = {self._id(mujoco.mjtObj.mjOBJ_GEOM, p) for p in finger_pads(side)}
        touching = set()
        for c in self.data.contact[: self.data.ncon]:
            pair = (int(c.geom[0]), int(c.geom[1]))
            if target in pair:
                touching.add(pair[0] if pair[1] == target else pair[1])
        return pads <= touching
