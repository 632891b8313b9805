"""What a simulated chain may sense beyond the `Robot` interface: scene geometry and contacts (sim only)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.tasks.scenes import finger_pads, grasp_site


@dataclass(frozen=True)
class BarInHand:
    offset: np.ndarray
    """The bar's axis point nearest the grasp site, in the site's frame (y along the fingers, z the closing axis), m."""
    to_end: float
    """From the grasp site to the nearer end of the bar's straight part, along the bar, m (negative: past it)."""


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
            what = {mujoco.mjtObj.mjOBJ_GEOM: "geom", mujoco.mjtObj.mjOBJ_SITE: "site"}.get(kind, "body")
            raise ToddlerbotError(f"the scene has no {what} named {name!r}")
        return i

    def geom_pos(self, name: str) -> np.ndarray:
        """World position of a geom's centre, m."""
        return self.data.geom_xpos[self._id(mujoco.mjtObj.mjOBJ_GEOM, name)].copy()

    def displacement(self, body: str) -> float:
        """Horizontal distance a body moved since `mark`, m."""
        i = self._id(mujoco.mjtObj.mjOBJ_BODY, body)
        return float(np.linalg.norm(self.data.xpos[i, :2] - self._start[i, :2]))

    def rise(self, body: str) -> float:
        """How far a body's origin rose since `mark`, m (negative: it went down)."""
        i = self._id(mujoco.mjtObj.mjOBJ_BODY, body)
        return float(self.data.xpos[i, 2] - self._start[i, 2])

    def _pad_contacts(self, side: str, geom: str) -> Iterator[tuple[int, int]]:
        """(finger pad geom id, contact index) of each contact between `geom` and a pad of the `side` gripper."""
        target = self._id(mujoco.mjtObj.mjOBJ_GEOM, geom)
        pads = {self._id(mujoco.mjtObj.mjOBJ_GEOM, p) for p in finger_pads(side)}
        for i, c in enumerate(self.data.contact[: self.data.ncon]):
            a, b = int(c.geom[0]), int(c.geom[1])
            if target in (a, b) and (pad := a if b == target else b) in pads:
                yield pad, i

    def pinching(self, side: str, geom: str) -> bool:
        """Do both finger pads of the `side` gripper touch `geom`?"""
        return len({pad for pad, _ in self._pad_contacts(side, geom)}) == 2

    def pad_forces(self, side: str, geom: str) -> np.ndarray:
        """Normal force `geom` presses on each finger pad of the `side` gripper (pad, mirror pad), N."""
        pads = [self._id(mujoco.mjtObj.mjOBJ_GEOM, p) for p in finger_pads(side)]
        forces, wrench = np.zeros(2), np.zeros(6)
        for pad, i in self._pad_contacts(side, geom):
            mujoco.mj_contactForce(self.model, self.data, i, wrench)
            forces[pads.index(pad)] += wrench[0]
        return forces

    def bar_in_hand(self, side: str, geom: str) -> BarInHand:
        """Where a bar (capsule or cylinder `geom`, axis along its z) lies in the `side` gripper."""
        g = self._id(mujoco.mjtObj.mjOBJ_GEOM, geom)
        site = self._id(mujoco.mjtObj.mjOBJ_SITE, grasp_site(side))
        axis, centre = self.data.geom_xmat[g].reshape(3, 3)[:, 2], self.data.geom_xpos[g]
        pos, rot = self.data.site_xpos[site], self.data.site_xmat[site].reshape(3, 3)
        along = float(axis @ (pos - centre))
        return BarInHand(rot.T @ (centre + along * axis - pos), float(self.model.geom_size[g, 1]) - abs(along))
