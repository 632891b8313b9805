"""The robot drawn in a viser scene from the compiled model's geoms, plus the balance overlay.

The model is made of primitives only (boxes, cylinders, capsules, spheres), so the robot is three batched
meshes (unit box, unit cylinder, unit sphere; capsules are a cylinder and two end spheres) whose instances take
each geom's pose and size: one frame of motion is a handful of array messages, not one per geom. Meshes are built
here, so the page fetches nothing from outside (viser serves its own client).
"""

from __future__ import annotations

import mujoco
import numpy as np
import trimesh
import viser

from toddlerbot.motion_editor.balance import Balance
from toddlerbot.robot.builder import COLLISION_GROUP, SKELETON_GROUP
from toddlerbot.robot.visuals import VISUAL_GROUP

_BOX, _CAPSULE, _SPHERE, _CYLINDER = (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_CAPSULE,
                                      mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CYLINDER)
GREEN, RED = (40, 170, 70), (220, 50, 40)
FLOOR_Z = 0.001
"""Overlay lines sit this far above the floor, m (not hidden in it)."""
CROSS_M = 0.015
"""Half-size of the cross marking the CoM's ground projection, m."""
SEE_THROUGH_OPACITY = 0.45


class RobotScene:
    def __init__(self, server: viser.ViserServer, model: mujoco.MjModel, root: str = "/robot") -> None:
        self.server = server
        self.model = model
        geoms = drawn_geoms(model)
        self._boxes = [g for g in geoms if model.geom_type[g] == _BOX]
        self._sticks = [g for g in geoms if model.geom_type[g] in (_CAPSULE, _CYLINDER)]
        self._balls = [g for g in geoms if model.geom_type[g] == _SPHERE]
        self._caps = [g for g in self._sticks if model.geom_type[g] == _CAPSULE]
        size = model.geom_size
        self._handles = {}
        for key, ids, mesh, scale in (
            ("boxes", self._boxes, trimesh.creation.box((2.0, 2.0, 2.0)), size[self._boxes]),
            ("sticks", self._sticks, trimesh.creation.cylinder(1.0, 2.0, sections=16),
             size[self._sticks][:, [0, 0, 1]]),
            ("balls", self._balls + self._caps * 2, trimesh.creation.icosphere(2, 1.0),
             size[self._balls + self._caps * 2][:, [0, 0, 0]]),
        ):
            if not ids:
                continue
            n = len(ids)
            self._handles[key] = server.scene.add_batched_meshes_simple(
                f"{root}/{key}", mesh.vertices, mesh.faces, np.tile([1.0, 0, 0, 0], (n, 1)), np.zeros((n, 3)),
                batched_scales=np.asarray(scale, dtype=float),
                batched_colors=(model.geom_rgba[ids, :3] * 255).astype(np.uint8), lod="off")
        server.scene.add_grid("/floor", width=2.0, height=2.0, cell_size=0.1, section_size=0.5, position=(0, 0, 0))
        self._com = server.scene.add_icosphere("/balance/com", radius=0.012, color=GREEN)
        self._drop = server.scene.add_line_segments("/balance/com_drop", np.zeros((1, 2, 3)), GREEN, thickness=3.0,
                                                    thickness_units="screen")
        self._polygon = server.scene.add_line_segments("/balance/support", np.zeros((1, 2, 3)), GREEN, thickness=4.0,
                                                       thickness_units="screen")

    def see_through(self, on: bool) -> None:
        """Draw the robot translucent, so the CoM marker inside it shows."""
        for handle in self._handles.values():
            handle.opacity = SEE_THROUGH_OPACITY if on else None

    def show(self, data: mujoco.MjData, balance: Balance | None = None) -> None:
        """Draw the robot in state `data` (positions from `mj_kinematics`) and, if given, its balance."""
        with self.server.atomic():
            xpos, xmat = data.geom_xpos, data.geom_xmat
            quat = _quats(xmat)
            if "boxes" in self._handles:
                self._handles["boxes"].batched_positions = xpos[self._boxes]
                self._handles["boxes"].batched_wxyzs = quat[self._boxes]
            if "sticks" in self._handles:
                self._handles["sticks"].batched_positions = xpos[self._sticks]
                self._handles["sticks"].batched_wxyzs = quat[self._sticks]
            if "balls" in self._handles:
                caps = self._caps
                axis = xmat[caps].reshape(-1, 3, 3)[:, :, 2] * self.model.geom_size[caps, 1:2]
                ends = np.concatenate([xpos[caps] + axis, xpos[caps] - axis])
                self._handles["balls"].batched_positions = np.concatenate([xpos[self._balls], ends])
                self._handles["balls"].batched_wxyzs = np.tile([1.0, 0, 0, 0], (len(self._balls) + 2 * len(caps), 1))
            if balance is not None:
                self.show_balance(balance)

    def show_balance(self, balance: Balance) -> None:
        color = GREEN if balance.supported else RED
        com = balance.com
        self._com.position = tuple(com)
        self._com.color = color
        foot = np.array([com[0], com[1], FLOOR_Z])
        cross = CROSS_M * np.array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0]])
        self._drop.points = np.array([[com, foot], [foot - cross[0], foot + cross[0]],
                                      [foot - cross[1], foot + cross[1]]])
        self._drop.colors = _colors(color, 3)
        poly = balance.polygon
        if len(poly) >= 2:
            ring = np.column_stack([poly, np.full(len(poly), FLOOR_Z)])
            self._polygon.points = np.stack([ring, np.roll(ring, -1, axis=0)], axis=1)
            self._polygon.colors = _colors(color, len(ring))
            self._polygon.visible = True
        else:
            self._polygon.visible = False


def _colors(rgb: tuple[int, int, int], segments: int) -> np.ndarray:
    return np.tile(np.array(rgb, dtype=np.uint8), (segments, 2, 1))


def drawn_geoms(model: mujoco.MjModel) -> list[int]:
    """The robot's geoms as `sim run --video` draws them: the visual geometry, or where the model has none the
    collision primitives and the skeleton of thin links (the floor is drawn as a grid instead)."""
    robot = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0]
    visual = [g for g in robot if model.geom_group[g] == VISUAL_GROUP]
    return visual or [g for g in robot if model.geom_group[g] in (COLLISION_GROUP, SKELETON_GROUP)]


def _quats(xmat: np.ndarray) -> np.ndarray:
    out = np.empty((len(xmat), 4))
    for i, mat in enumerate(xmat):
        mujoco.mju_mat2Quat(out[i], mat)
    return out
