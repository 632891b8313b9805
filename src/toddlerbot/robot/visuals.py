"""The robot's visual geometry, generated from the spec and the motor catalogue (no meshes, no copied CAD).

Scene renders draw these geoms; physics and the head camera do not. The builder adds them with contype =
conaffinity = 0 (no contacts), every body keeps its explicit inertial (no mass or inertia from them), and they live
in `VISUAL_GROUP`, a geom group MuJoCo leaves hidden unless a renderer asks for it: the head camera, whose 96x96
images the diffusion policies were trained on, keeps rendering the collision shapes it always rendered.

What is drawn, and what is approximate:

* **Motor housings**: one black box per Dynamixel at its catalogue ``dimensions_mm`` (W x H x D), in the heavier of
  the two bodies its joint connects (that body's inertial carries the motor's mass), its horn at the joint. A
  single-axis housing turns about the joint axis along D with its shaft W/2 from one end of H; which side of the horn
  it sits on and its roll about the shaft are estimates: of 16 placements (2 sides x 8 rolls) the one reaching least
  outside the link's collision primitives (the reference's bounding shapes of link and motors) wins, at most 6 mm
  outside. A dual-axis unit (2XL430, 2XC430: two motor entries held by the same body) is one box whose horns sit on
  two perpendicular faces at the two joints, its long side across both shafts; that puts the arm units where the
  reference model's bounding spheres are (centres 2.5 mm apart).
* **Printed links**: shells `Appearance.shell_margin` outside each collision box, capsule and cylinder; a box mostly
  filled with motors (`Appearance.bracket_fill`: thighs, ankle links) is a servo bracket instead, two side plates
  across its heaviest motor's shaft with the black motors showing between them. Collision spheres are the
  reference's bounding spheres of the arm motor units, whose housings are drawn instead. A link without a collision
  primitive gets a bar to each child link (upper arm, forearm, calf, neck, hip and shoulder brackets); linkage rods
  are thin bars as long as twice their centre of mass is from their pin (uniform rods). Links alternate white and
  light grey along each limb (by the parity of the output joints from the torso), as on the printed robot; which
  part is which colour on the real robot is not in the spec.
* **Camera**: a lens (black barrel, dark glass) at each spec camera's pose, looking where the camera looks.
* **Gripper jaws** (gripper variant): per rack-and-pinion finger, a printed jaw plate whose inner face is the
  rack's travel from the closing axis' centre when open (so the jaws meet when closed), the size of the finger's
  collision box across the closing axis, and a black rack along it.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from toddlerbot.actuation.catalogue import Catalogue
from toddlerbot.robot.spec import (
    BevelDifferential,
    BodySpec,
    MotorSpec,
    ParallelLinkage,
    RackAndPinion,
    RobotSpec,
    SpurGear,
)

VISUAL_GROUP = 3
"""Geom group of the visual geometry. MuJoCo renders groups 0-2 by default, so cameras that do not ask for group 3
(the head camera) see the model as it was before visuals existed; `toddlerbot.sim.render` asks for it."""

RGBA = tuple[float, float, float, float]
GeomType = Literal["box", "sphere", "capsule", "cylinder"]
FinishName = Literal["printed", "motor", "glass"]


@dataclass(frozen=True)
class Finish:
    """How a surface takes the light (MuJoCo material properties, each 0-1)."""

    emission: float
    """Light of its own: lifts the printed parts' sides, which the scene's overhead light leaves dark."""
    specular: float
    shininess: float


FINISHES: dict[FinishName, Finish] = {
    "printed": Finish(emission=0.3, specular=0.15, shininess=0.2),  # matte plastic
    "motor": Finish(emission=0.0, specular=0.5, shininess=0.6),     # satin black housings, metal horns
    "glass": Finish(emission=0.0, specular=1.0, shininess=1.0),
}
"""Materials of the visual geometry (the scene's lights are left as they are: the head camera sees them)."""


@dataclass(frozen=True)
class Appearance:
    """Colours and the few sizes the spec and the catalogue do not give; lengths in m."""

    motor: RGBA = (0.06, 0.06, 0.07, 1.0)
    """Dynamixel housings."""
    horn: RGBA = (0.42, 0.43, 0.45, 1.0)
    """Motor horns (output discs)."""
    printed: tuple[RGBA, RGBA] = ((0.95, 0.95, 0.93, 1.0), (0.74, 0.76, 0.78, 1.0))
    """Printed links: white, light grey; they alternate along each limb."""
    lens: RGBA = (0.02, 0.02, 0.02, 1.0)
    glass: RGBA = (0.1, 0.16, 0.3, 1.0)
    shell_margin: float = 0.002
    """How far a printed shell stands off its collision primitive."""
    bar_half_width: float = 0.009
    """Half the width of the printed bar drawn for a link without a collision primitive."""
    rod_radius: float = 0.0018
    """Linkage rods."""
    horn_radius: float = 0.35
    """Horn radius as a fraction of the housing's smallest side."""
    horn_half_thickness: float = 0.0012
    lens_radius: float = 0.007
    lens_half_length: float = 0.004
    """How far the lens barrel reaches in front of and behind the camera's position."""
    bracket_fill: float = 0.2
    """A collision box whose motor housings fill at least this fraction of it is a servo bracket (two side plates,
    motors showing), not a closed shell: measured, the thighs (24 %) and ankle links (49 %) are; the torso (5 %),
    head (3 %) and pelvis (7 %) are not."""
    jaw_half_thickness: float = 0.003
    rack_half_width: float = 0.003


@dataclass(frozen=True)
class VisualGeom:
    """One visual primitive in a body's frame (MuJoCo's conventions: half sizes; capsules and cylinders along z)."""

    name: str
    body: str
    type: GeomType
    size: tuple[float, float, float]
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    rgba: RGBA
    finish: FinishName = "printed"


def visual_geoms(spec: RobotSpec, catalogue: Catalogue, appearance: Appearance = Appearance()) -> list[VisualGeom]:
    """Every visual geom of the robot, in a deterministic order."""
    housings = place_housings(spec, catalogue)
    return [
        *motor_housings(housings, appearance),
        *printed_links(spec, housings, appearance),
        *camera_lenses(spec, appearance),
        *gripper_jaws(spec, appearance),
    ]


# ---- frames ----------------------------------------------------------------------------------------------------
def _rot(quat) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, dtype=float) / np.linalg.norm(quat))
    return mat.reshape(3, 3)


def _quat(rot: np.ndarray) -> tuple[float, float, float, float]:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rot, dtype=float).ravel())
    return _tuple(quat)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # np.cross costs ~50x more for single 3-vectors, and placing the housings takes hundreds
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _tuple(values) -> tuple:
    return tuple(np.round(np.asarray(values, dtype=float), 9).tolist())  # 9 digits: the same MJCF everywhere


def _frame_with_z(z: np.ndarray, hint: np.ndarray | None = None) -> np.ndarray:
    """A rotation whose third column is `z`; its first column lies along `hint` (made perpendicular) if given."""
    z = z / np.linalg.norm(z)
    for candidate in (hint, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        if candidate is None:
            continue
        x = candidate - (candidate @ z) * z
        if np.linalg.norm(x) > 1e-6:
            x /= np.linalg.norm(x)
            return np.column_stack([x, _cross(z, x), z])
    raise AssertionError("unreachable: x and y cannot both be parallel to z")


def _segment(name: str, body: str, start: np.ndarray, end: np.ndarray, half_width: float, rgba: RGBA,
             kind: GeomType, hint: np.ndarray | None = None, finish: FinishName = "printed") -> VisualGeom:
    """A box (square section) or capsule from `start` to `end` in `body`'s frame."""
    half_length = float(np.linalg.norm(end - start)) / 2
    size = (half_width, half_width, half_length) if kind == "box" else (half_width, half_length, 0.0)
    return VisualGeom(name, body, kind, _tuple(size), _tuple((start + end) / 2),
                      _quat(_frame_with_z(end - start, hint)), rgba, finish)


# ---- motor housings --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Shaft:
    """A motor's output shaft, in the frame of the body holding the motor's housing."""

    motor: MotorSpec
    holder: str
    point: np.ndarray
    """Where the joint axis meets the horn, m."""
    axis: np.ndarray
    """Unit joint axis."""
    behind: np.ndarray
    """Unit vector along the axis from the horn into the housing (away from the driven link)."""


_AXIAL_TOLERANCE = 1e-3
"""m: a centre of mass closer than this to the horn's plane says nothing about which side the housing is on."""


def motor_shafts(spec: RobotSpec) -> list[Shaft]:
    """Each motor's shaft in the heavier of the two bodies its joint connects, in motor-id order."""
    bodies = {b.name: b for b in spec.bodies}
    body_of_joint = spec.body_of_joint  # a dict built on each access
    shafts = []
    for motor in spec.motors_by_id:
        child = bodies[body_of_joint[motor.joint]]
        parent = bodies[child.parent]
        joint, rot = child.joint, _rot(child.quat)
        if parent.mass >= child.mass:  # the housing is fixed to the parent; the child turns with the horn
            holder, point, axis = parent, child.pos + rot @ joint.pos, rot @ joint.axis
            driven_com = child.pos + rot @ child.com
        else:
            holder, point, axis = child, np.array(joint.pos), np.array(joint.axis)
            driven_com = rot.T @ (np.array(parent.com) - child.pos)
        axis = axis / np.linalg.norm(axis)
        lean = (driven_com - point) @ axis
        if abs(lean) < _AXIAL_TOLERANCE:
            lean = -(np.array(holder.com) - point) @ axis
        shafts.append(Shaft(motor, holder.name, np.asarray(point, float), axis, -axis if lean > 0 else axis))
    return shafts


@dataclass(frozen=True)
class Housing:
    """A placed motor housing: one per single-axis motor, one per dual-axis unit (two shafts)."""

    holder: str
    shafts: tuple[Shaft, ...]
    centre: np.ndarray
    rot: np.ndarray
    """Columns: the box's axes in the holder's frame (its half sizes are `dims` / 2 along them)."""
    dims: np.ndarray
    """Catalogue W x H x D, m."""
    behind: tuple[np.ndarray, ...]
    """Per shaft: the unit vector from its horn into the housing."""
    mass: float
    """kg (the catalogue's)."""


def place_housings(spec: RobotSpec, catalogue: Catalogue) -> list[Housing]:
    """Every motor housing, in the order of the first motor id of each."""
    bodies = {b.name: b for b in spec.bodies}
    units: list[list[Shaft]] = []
    dual: dict[tuple[str, str], list[Shaft]] = defaultdict(list)
    for shaft in motor_shafts(spec):
        if catalogue[shaft.motor.model].axes == 2:
            dual[(shaft.holder, catalogue[shaft.motor.model].name)].append(shaft)
        else:
            units.append([shaft])
    for shafts in dual.values():  # the two axes of one unit are held by the same body; pair them in id order
        units.extend(shafts[i : i + 2] for i in range(0, len(shafts), 2))
    units.sort(key=lambda unit: unit[0].motor.id)
    housings = []
    for unit in units:
        model = catalogue[unit[0].motor.model]
        dims = np.array(model.dimensions_mm) / 1000.0
        if len(unit) == 2 and np.linalg.norm(_cross(unit[0].axis, unit[1].axis)) > 0.5:
            centre, rot, behind = _dual_housing(unit[0], unit[1], dims)
        else:
            centre, rot, inward = _single_housing(unit[0], bodies[unit[0].holder], dims)
            behind = [inward]
        housings.append(Housing(unit[0].holder, tuple(unit), centre, rot, dims, tuple(behind), model.mass_kg))
    return housings


def motor_housings(housings: list[Housing], appearance: Appearance = Appearance()) -> list[VisualGeom]:
    """The housings (`place_housings`) as black boxes, a horn on each shaft."""
    geoms = []
    for h in housings:
        geoms.append(VisualGeom(f"{h.shafts[0].motor.joint}_motor", h.holder, "box", _tuple(h.dims / 2),
                                _tuple(h.centre), _quat(h.rot), appearance.motor, "motor"))
        for shaft, behind in zip(h.shafts, h.behind):
            geoms.append(VisualGeom(
                f"{shaft.motor.joint}_horn", h.holder, "cylinder",
                _tuple((appearance.horn_radius * min(h.dims), appearance.horn_half_thickness, 0.0)),
                _tuple(shaft.point - behind * appearance.horn_half_thickness), _quat(_frame_with_z(behind)),
                appearance.horn, "motor",
            ))
    return geoms


_ROLL_STEPS = 8
"""Orientations about the shaft tried for a single-axis housing (45 degrees apart), on each side of the horn."""


def _single_housing(shaft: Shaft, holder: BodySpec, dims: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre, orientation (columns: W, H, D directions) and inward direction of a single-axis housing.

    Of the placements with the horn at the joint (either side of it, H turned about the shaft in 45-degree steps)
    the one reaching least outside the holder's collision primitives (the reference's bounding shapes of the link
    and its motors) wins; ties keep the first: behind the horn, H towards the holder's centre of mass."""
    width, height, depth = dims
    towards_mass = _frame_with_z(shaft.behind, np.array(holder.com) - shaft.point)[:, 0]
    angles = 2 * np.pi * np.arange(_ROLL_STEPS) / _ROLL_STEPS
    along_h = np.outer(np.cos(angles), towards_mass) + np.outer(np.sin(angles), _cross(shaft.behind, towards_mass))
    behind = np.repeat([shaft.behind, -shaft.behind], _ROLL_STEPS, axis=0)  # placements: side-major order
    along_h = np.tile(along_h, (2, 1))
    centres = shaft.point + behind * depth / 2 + along_h * (height - width) / 2
    rots = np.stack([np.cross(along_h, behind), along_h, behind], axis=-1)  # (placement, xyz, WHD)
    points = centres[:, None, :] + np.einsum("pij,sj->psi", rots, _BOX_SAMPLES * dims / 2)
    outside = _outside(points.reshape(-1, 3), holder.collision).reshape(len(centres), -1).sum(axis=1)
    best = int(np.argmin(np.round(outside, 9)))  # the first of equals
    return centres[best], rots[best], behind[best]


_BOX_SAMPLES = np.array([(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)], dtype=float)
"""Corners, edge and face centres and the centre of a unit box (scaled by half sizes)."""


def _outside(points: np.ndarray, geoms) -> np.ndarray:
    """Each of `points`' (body frame) distance outside the nearest of `geoms`, m (zeros without geoms)."""
    distances = [np.zeros(len(points))]
    for g in geoms:
        local = (points - np.array(g.pos)) @ _rot(g.quat)
        size = np.array(g.size)
        if g.type == "box":
            distances.append(np.linalg.norm(np.maximum(np.abs(local) - size, 0.0), axis=1))
        elif g.type == "sphere":
            distances.append(np.maximum(np.linalg.norm(local, axis=1) - size[0], 0.0))
        else:  # capsule or cylinder along z
            radial = np.linalg.norm(local[:, :2], axis=1)
            beyond = np.maximum(np.abs(local[:, 2]) - size[1], 0.0)
            distances.append(np.maximum(np.hypot(radial, beyond) - size[0], 0.0) if g.type == "capsule"
                             else np.hypot(np.maximum(radial - size[0], 0.0), beyond))
    return np.min(distances[1:], axis=0) if geoms else distances[0]


def _dual_housing(a: Shaft, b: Shaft, dims: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Centre, orientation (columns: long side, a's axis, b's axis) and each horn's inward direction of a
    dual-axis housing with its horns on two perpendicular faces at the shafts, its long side centred between them."""
    _, across_a, across_b = dims
    axis_a = a.axis
    axis_b = b.axis - (b.axis @ axis_a) * axis_a
    axis_b /= np.linalg.norm(axis_b)
    long_side = _cross(axis_a, axis_b)
    behind_a = axis_a * (1.0 if (b.point - a.point) @ axis_a >= 0 else -1.0)
    behind_b = axis_b * (1.0 if (a.point - b.point) @ axis_b >= 0 else -1.0)
    centre = (long_side * ((a.point + b.point) @ long_side / 2)
              + axis_a * (a.point @ axis_a + (behind_a @ axis_a) * across_a / 2)
              + axis_b * (b.point @ axis_b + (behind_b @ axis_b) * across_b / 2))
    return centre, np.column_stack([long_side, axis_a, axis_b]), [behind_a, behind_b]


# ---- printed links ---------------------------------------------------------------------------------------------
def transmission_parts(spec: RobotSpec) -> set[str]:
    """Bodies that are gears, cranks, rods or bearings of a transmission rather than printed links."""
    joints: set[str] = set()
    for t in spec.transmissions:
        if isinstance(t, (SpurGear, RackAndPinion)):
            joints.add(t.drive)
        elif isinstance(t, ParallelLinkage):
            joints.add(t.drive)
            joints.update(j for pair in t.rods for j in (pair.rod, pair.bearing))
        elif isinstance(t, BevelDifferential):
            joints.update(t.drives)
    body_of_joint = spec.body_of_joint
    return {body_of_joint[j] for j in joints}


def link_colour_index(spec: RobotSpec) -> dict[str, int]:
    """0 (white) or 1 (grey) per body: the parity of the output joints between it and the root."""
    parts = transmission_parts(spec)
    index: dict[str, int] = {}
    for body in spec.bodies:  # parents come before children
        above = index.get(body.parent, 0)
        index[body.name] = (above + 1) % 2 if body.joint is not None and body.name not in parts else above
    return index


def _rack_fingers(spec: RobotSpec) -> set[str]:
    return {spec.body_of_joint[j] for t in spec.transmissions if isinstance(t, RackAndPinion) for j in t.driven}


def printed_links(spec: RobotSpec, placed: list[Housing], appearance: Appearance = Appearance()) -> list[VisualGeom]:
    """Shells (or brackets, around the `placed` housings) over the collision primitives, bars for links without
    one, linkage rods."""
    parts, fingers = transmission_parts(spec), _rack_fingers(spec)
    housings: dict[str, list[Housing]] = defaultdict(list)
    for h in placed:
        housings[h.holder].append(h)
    colour = link_colour_index(spec)
    rods = {spec.body_of_joint[p.rod] for t in spec.transmissions if isinstance(t, ParallelLinkage) for p in t.rods}
    children: dict[str, list[BodySpec]] = defaultdict(list)
    for body in spec.bodies:
        children[body.parent].append(body)
    margin = appearance.shell_margin
    geoms = []
    for body in spec.bodies:
        rgba = appearance.printed[colour[body.name]]
        if body.name in fingers:
            continue  # drawn as jaws
        for g in body.collision:
            if g.type == "sphere":
                continue  # a motor unit's bounding sphere: the housing is drawn
            inside = [h for h in housings[body.name] if _outside(h.centre[None, :], [g])[0] == 0.0]
            if g.type == "box" and sum(np.prod(h.dims) for h in inside) >= appearance.bracket_fill * np.prod(
                    2 * np.array(g.size)):
                geoms.extend(_bracket(g, body.name, max(inside, key=lambda h: h.mass), rgba, margin))
                continue
            size = [s + margin for s in g.size] if g.type == "box" else [g.size[0] + margin, g.size[1], 0.0]
            geoms.append(VisualGeom(f"{g.name}_shell", body.name, g.type, _tuple(size), _tuple(g.pos),
                                    _tuple(g.quat), rgba))
        if body.name in rods:
            geoms.append(_segment(f"{body.name}_rod", body.name, np.zeros(3), 2 * np.array(body.com),
                                  appearance.rod_radius, appearance.horn, "capsule", finish="motor"))
        if body.collision or body.name in parts or body.parent == "world":
            continue
        for child in children[body.name]:
            if child.name in parts or np.linalg.norm(child.pos) < appearance.bar_half_width:
                continue
            hint = np.array(body.joint.axis) if body.joint is not None else None
            geoms.append(_segment(f"{child.name}_bracket", body.name, np.zeros(3), np.array(child.pos),
                                  appearance.bar_half_width, rgba, "box", hint))
    return geoms


def _bracket(g, body: str, motor: Housing, rgba: RGBA, margin: float) -> list[VisualGeom]:
    """Two plates `margin` thick on the faces of box `g` across `motor`'s (first) shaft, so the motors between
    them show, as a printed bracket holds a servo by its sides."""
    rot = _rot(g.quat)
    axis = int(np.argmax(np.abs(rot.T @ motor.shafts[0].axis)))  # the box axis closest to the shaft
    size = np.array(g.size) + margin
    size[axis] = margin / 2
    plates = []
    for side, sign in (("a", 1.0), ("b", -1.0)):
        offset = np.zeros(3)
        offset[axis] = sign * (g.size[axis] + margin / 2)
        plates.append(VisualGeom(f"{g.name}_bracket_{side}", body, "box", _tuple(size),
                                 _tuple(np.array(g.pos) + rot @ offset), _tuple(g.quat), rgba))
    return plates


# ---- camera and jaws -------------------------------------------------------------------------------------------
def camera_lenses(spec: RobotSpec, appearance: Appearance = Appearance()) -> list[VisualGeom]:
    """A lens barrel and its glass at each camera, reaching `shell_margin` past the camera's position."""
    geoms = []
    for body in spec.bodies:
        for cam in body.cameras:
            look = -_rot(cam.quat)[:, 2]  # cameras look along their local -z
            centre = np.array(cam.pos) + look * appearance.shell_margin
            r, h = appearance.lens_radius, appearance.lens_half_length
            geoms.append(VisualGeom(f"{cam.name}_lens", body.name, "cylinder", _tuple((r, h, 0.0)), _tuple(centre),
                                    _tuple(cam.quat), appearance.lens, "motor"))
            geoms.append(VisualGeom(f"{cam.name}_glass", body.name, "cylinder", _tuple((0.6 * r, h + 0.0005, 0.0)),
                                    _tuple(centre), _tuple(cam.quat), appearance.glass, "glass"))
    return geoms


def gripper_jaws(spec: RobotSpec, appearance: Appearance = Appearance()) -> list[VisualGeom]:
    """Jaw plates and racks of every rack-and-pinion gripper (in each finger's frame)."""
    bodies = {b.name: b for b in spec.bodies}
    colour = link_colour_index(spec)
    geoms = []
    for t in spec.transmissions:
        if not isinstance(t, RackAndPinion):
            continue
        fingers = [bodies[spec.body_of_joint[j]] for j in t.driven]
        # each finger's collision box centre in the gripper's frame, and where the fingers close
        centres = [f.pos + _rot(f.quat) @ np.array(f.collision[0].pos) for f in fingers]
        middle = np.mean(centres, axis=0)
        for finger in fingers:
            rot, box = _rot(finger.quat), finger.collision[0]
            box_rot, box_pos, half = _rot(box.quat), np.array(box.pos), np.array(box.size)
            slide = np.array(finger.joint.axis) / np.linalg.norm(finger.joint.axis)
            travel = finger.joint.range[1] - finger.joint.range[0] if finger.joint.range else 0.0
            middle_local = rot.T @ (middle - finger.pos)
            side = 1.0 if (box_pos - middle_local) @ slide >= 0 else -1.0
            across = 1.0 - np.abs(box_rot.T @ slide)  # per box axis: 1 across the slide, 0 along it
            plate = half * across + appearance.jaw_half_thickness * (1.0 - across)
            inner = middle_local @ slide + side * (travel + appearance.jaw_half_thickness)
            jaw_pos = box_pos + (inner - box_pos @ slide) * slide
            geoms.append(VisualGeom(f"{finger.name}_jaw", finger.name, "box", _tuple(plate), _tuple(jaw_pos),
                                    _quat(box_rot), appearance.printed[colour[finger.name]]))
            rack = np.where(across > 0.5, appearance.rack_half_width, half)
            geoms.append(VisualGeom(f"{finger.name}_rack", finger.name, "box", _tuple(rack), _tuple(box_pos),
                                    _quat(box_rot), appearance.motor, "motor"))
    return geoms
