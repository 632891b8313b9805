"""Where the robot's weight is: a pose placed on the floor, its centre of mass and its support polygon.

For an edited keyframe (no physics) the robot stands upright with its lowest collision point on the floor (or lies
as the keyframe's base pose says: `robot.floor_pose`), and the support polygon is the convex hull of the sole
corners within `SOLE_CONTACT_M` of the floor. In a simulated
run it is the hull of the robot's contact points with the floor. Statically the robot is balanced when the
CoM's ground projection lies inside the polygon; `margin` is its distance to the nearest edge (negative outside).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.policies.motions import BasePose
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.floor_pose import place_on_floor

SOLE_CONTACT_M = 0.003
"""A sole corner this close to the floor, m, counts as touching it."""


@dataclass(frozen=True)
class Balance:
    com: np.ndarray
    """(3,) whole-robot centre of mass in the world, m."""
    polygon: np.ndarray
    """(k, 2) support polygon on the floor, counter-clockwise, m (k = 0 when nothing touches)."""
    margin: float
    """Distance from the CoM's ground projection to the polygon's nearest edge, m: > 0 inside, < 0 outside
    (-inf without a polygon)."""

    @property
    def supported(self) -> bool:
        return self.margin > 0

    def describe(self) -> str:
        if len(self.polygon) < 3:
            return "no support polygon (fewer than three points on the floor)"
        where = "inside" if self.supported else "outside"
        return f"CoM {abs(self.margin) * 1000:.0f} mm {where} the support polygon"


class PoseModel:
    """Kinematic poses of one robot: output-joint angles -> MjData with the feet on the floor, and its balance."""

    def __init__(self, description: RobotDescription) -> None:
        self.description = description
        self.model = description.model("floating", scene=True)
        self.data = mujoco.MjData(self.model)
        self._torso = self.model.body(description.handles.torso).id
        self._feet = [self.model.geom(g).id for g in description.handles.feet_geoms]
        self._floor = self.model.geom("floor").id

    def pose(self, joint_pos: np.ndarray, base: BasePose | None = None) -> mujoco.MjData:
        """Joints at `joint_pos` (rad, `joint_names` order), the torso upright (or as `base` says), lowest point on
        the floor (or the torso frame at the base's height)."""
        m, d = self.model, self.data
        base = base or BasePose()
        place_on_floor(m, d, self.description.transmission, joint_pos, base.roll, base.pitch, base.z)
        mujoco.mj_comPos(m, d)
        return d

    def static_balance(self) -> Balance:
        """Balance of the pose last set by `pose` (sole corners near the floor)."""
        corners = np.concatenate([box_corners(self.model, self.data, g) for g in self._feet])
        on_floor = corners[corners[:, 2] < SOLE_CONTACT_M]
        return balance_of(self.data.subtree_com[self._torso], on_floor[:, :2])

    def soles(self, data: mujoco.MjData) -> list[np.ndarray]:
        """Top-view outline of each sole in state `data`, (k, 2) m."""
        return [convex_hull(box_corners(self.model, data, g)[:, :2]) for g in self._feet]

    def contact_balance(self, data: mujoco.MjData) -> Balance:
        """Balance in a simulated state: the hull of the contact points with the floor."""
        return balance_of(data.subtree_com[self._torso], floor_contacts(data, self._floor))


def floor_contacts(data: mujoco.MjData, floor: int) -> np.ndarray:
    """(k, 2) horizontal positions of the contacts with geom `floor`, m."""
    n = data.ncon
    if n == 0:
        return np.zeros((0, 2))
    geoms = data.contact.geom[:n]
    touching = (geoms == floor).any(axis=1)
    return data.contact.pos[:n][touching, :2].copy()


def box_corners(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> np.ndarray:
    """(8, 3) world corners of box geom `geom`."""
    signs = np.array(list(itertools.product((-1, 1), repeat=3)), dtype=float)
    local = signs * model.geom_size[geom]
    return data.geom_xpos[geom] + local @ data.geom_xmat[geom].reshape(3, 3).T


def balance_of(com: np.ndarray, points: np.ndarray) -> Balance:
    hull = convex_hull(points)
    return Balance(np.array(com, dtype=float), hull, signed_margin(np.asarray(com)[:2], hull))


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise hull of 2-D points (monotone chain); collinear and repeated points dropped."""
    pts = sorted({(round(float(x), 6), round(float(y), 6)) for x, y in np.asarray(points).reshape(-1, 2)})
    if len(pts) < 3:
        return np.array(pts, dtype=float).reshape(-1, 2)

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def chain(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2 and cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.array(chain(pts) + chain(reversed(pts)), dtype=float)


def signed_margin(point: np.ndarray, polygon: np.ndarray) -> float:
    """Distance from `point` to the nearest edge of a counter-clockwise convex polygon, > 0 inside."""
    if len(polygon) < 3:
        return -np.inf
    a, b = polygon, np.roll(polygon, -1, axis=0)
    edge = b - a
    rel = np.asarray(point) - a
    length = np.linalg.norm(edge, axis=1)
    inside_dist = (edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0]) / length  # left of each edge: inside
    if np.all(inside_dist >= 0):
        return float(inside_dist.min())
    s = np.clip(np.einsum("ij,ij->i", rel, edge) / length**2, 0.0, 1.0)
    return -float(np.min(np.linalg.norm(rel - s[:, None] * edge, axis=1)))
