"""Manipulation scenes for the gripper variant, built by adding to the robot's MjSpec (the builder is untouched).

`scene_model` compiles the scene of a registered task (`toddlerbot.tasks.TASKS`): the task's ``add_scene`` adds its
objects, then every scene gets the grasp sites and finger pads and a ``workspace`` camera looking at the area in
front of the robot. The building blocks of the shipped tasks' scenes live here:

* `add_pick_scene` (``pick``): the torso held in place by a weld to the world at its home pose (`mount_torso`: the
  legs keep standing on the floor but cannot tip over); a table in front of the robot with a 3 cm cube on it. The
  cube's start pose is set per episode (`place_cube`).
* `add_wagon_scene` (``wagon``): in front of the floating robot on the floor, a four-wheeled wagon whose handle bar
  sits at hand height, for grasp-then-walk skill chains (`shift_wagon` moves it).

World frame: x forward from the robot, y to its left, z up, origin on the floor under the torso.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.robot.builder import FREEJOINT, build_mjspec
from toddlerbot.robot.description import RobotDescription

CUBE_BODY = "cube"
CUBE_GEOM = "cube_geom"
TABLE_GEOM = "table_top"
WAGON_BODY = "wagon"
WAGON_HANDLE_GEOM = "wagon_handle"
WORKSPACE_CAMERA = "workspace"
SIDES = ("left", "right")


PAD_HALF_SIZE = (0.018, 0.0115, 0.0015)
"""Finger pad box half extents in the grasp-site frame (across the finger, along it, thickness), m: as wide as
the finger (the spec's finger box), so an off-centre cube is not squeezed out sideways."""
PAD_FRICTION = (2.0, 0.02, 0.001)
"""Finger pads' (rubber) sliding, torsional and rolling friction."""


def grasp_site(side: str) -> str:
    """Site midway between the two finger pads of one gripper (the point a grasp centres on the object).
    Its frame: y points from the wrist to the fingertips, z is the closing axis."""
    return f"{side}_grasp_center"


def finger_pads(side: str) -> tuple[str, str]:
    """Names of the two finger-pad geoms of one gripper."""
    return f"{side}_finger_pad", f"{side}_finger_mirror_pad"


@dataclass(frozen=True)
class PickLayout:
    """Table and cube of the ``pick`` scene; lengths in m, world frame."""

    table_center: tuple[float, float] = (0.15, -0.08)
    """(x, y) of the table top's centre (in front of the right hand, clear of the left one)."""
    table_half_size: tuple[float, float] = (0.07, 0.1)
    """(x, y) half extents of the table top."""
    table_height: float = 0.245
    """Height of the table top above the floor."""
    cube_half_size: float = 0.015
    cube_mass: float = 0.02
    """kg (a 3 cm wooden cube)."""
    cube_friction: float = 1.2


@dataclass(frozen=True)
class WagonLayout:
    """Wagon of the ``wagon`` scene; lengths in m, world frame, wagon facing -x (handle towards the robot)."""

    handle_x: float = 0.14
    """x of the handle bar's axis (in front of the robot's hands). The arms reach a bar further out or lower only
    with the fingers far from around it: at 0.175 m and 0.24 m the grasp point misses by 4 cm (DLS IK)."""
    handle_height: float = 0.26
    """Height of the handle bar above the floor (just below the hands' home height, elbows bent)."""
    handle_half_width: float = 0.18
    """Half length of the handle bar's straight part: with the chain's seeded ±3 cm wagon shift each hand's grasp
    point stays 3.8 cm from its end (the pads reach 1.8 cm either side of it); at 0.14 m one was 2 mm past it."""
    body_half_size: tuple[float, float, float] = (0.12, 0.1, 0.04)
    wheel_radius: float = 0.03
    mass: float = 0.4
    """kg, chassis."""
    handle_solref: tuple[float, float] = (0.005, 1.0)
    """Time constant (s) and damping ratio of the handle's contacts, which take priority over the finger pads': a
    rigid bar. MuJoCo scales contact stiffness with the bodies' mass, so at the default 0.02 s the few-gram fingers
    let the bar sink 3 mm into each pad at a 2 N pinch and the grip creeps (2 mm/s) while the robot walks."""
    handle_solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    """MuJoCo impedance (dmin, dmax, width m, midpoint, power) of the handle's contacts."""


def scene_model(description: RobotDescription, scene: str) -> mujoco.MjModel:
    """Compile the scene of the task registered as `scene` for a gripper-variant description (an unknown name is
    the registry's one-line error naming the known ones)."""
    from toddlerbot.tasks import GRIPPER, TASKS

    task = TASKS.get(scene)
    if description.spec.variant != GRIPPER:
        raise ValueError(f"the {scene} scene needs the gripper variant, got variant {description.spec.variant!r}")
    mj = build_mjspec(description.spec, "floating", scene=True, catalogue=description.catalogue)
    home = np.array(mj.key("home").qpos, dtype=float)
    extra_qpos = task.add_scene(mj, description, home)
    mj.key("home").qpos = np.concatenate([home, extra_qpos]).tolist()
    _add_grasp_sites_and_pads(mj, description)
    _add_workspace_camera(mj)
    mj.visual.global_.offwidth = max(mj.visual.global_.offwidth, 1280)
    return mj.compile()


def add_pick_scene(mj: mujoco.MjSpec, description: RobotDescription, home: np.ndarray,
                   layout: PickLayout = PickLayout()) -> np.ndarray:
    """The ``pick`` task's scene: the torso mounted, a table and a cube on it; returns the cube's home qpos."""
    mount_torso(mj, description, home)
    return add_table_and_cube(mj, layout)


def mount_torso(mj: mujoco.MjSpec, description: RobotDescription, home: np.ndarray) -> None:
    """Hold the torso where the home keyframe puts it (a weld to the world): the legs keep standing on the floor
    but cannot tip over."""
    model = mj.compile()  # relpose = world seen from the torso
    adr = model.joint(FREEJOINT).qposadr[0]
    torso_pos, torso_quat = home[adr : adr + 3], home[adr + 3 : adr + 7]
    world_in_torso_quat = np.zeros(4)
    mujoco.mju_negQuat(world_in_torso_quat, torso_quat)
    world_in_torso_pos = np.zeros(3)
    mujoco.mju_rotVecQuat(world_in_torso_pos, -torso_pos, world_in_torso_quat)
    weld = mj.add_equality(
        name="torso_mount", type=mujoco.mjtEq.mjEQ_WELD, objtype=mujoco.mjtObj.mjOBJ_BODY,
        name1=description.handles.torso, name2="world",
    )
    weld.data = np.concatenate([np.zeros(3), world_in_torso_pos, world_in_torso_quat, [1.0]]).tolist() + [0.0] * (
        len(weld.data) - 11
    )


def add_table_and_cube(mj: mujoco.MjSpec, layout: PickLayout = PickLayout()) -> np.ndarray:
    """A table in front of the robot and a cube (free joint) on it; returns the cube's home qpos."""
    (cx, cy), (hx, hy), h = layout.table_center, layout.table_half_size, layout.table_height
    wood = (0.55, 0.4, 0.28, 1.0)
    table = mj.worldbody.add_body(name="table", pos=(cx, cy, 0.0))
    table.add_geom(name=TABLE_GEOM, type=mujoco.mjtGeom.mjGEOM_BOX, size=(hx, hy, 0.01), pos=(0, 0, h - 0.01),
                   rgba=wood, contype=1, conaffinity=1)
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        table.add_geom(name=f"table_leg_{i}", type=mujoco.mjtGeom.mjGEOM_BOX, size=(0.008, 0.008, (h - 0.02) / 2),
                       pos=(sx * (hx - 0.01), sy * (hy - 0.01), (h - 0.02) / 2), rgba=wood, contype=0, conaffinity=0)

    s = layout.cube_half_size
    cube = mj.worldbody.add_body(name=CUBE_BODY, pos=(cx, cy, h + s))
    cube.add_freejoint(name=CUBE_BODY)
    cube.add_geom(name=CUBE_GEOM, type=mujoco.mjtGeom.mjGEOM_BOX, size=(s, s, s), mass=layout.cube_mass,
                  rgba=(0.85, 0.15, 0.15, 1.0), friction=(layout.cube_friction, 0.01, 0.001),
                  contype=1, conaffinity=1, condim=4)
    return np.array([cx, cy, h + s, 1.0, 0.0, 0.0, 0.0])


def add_wagon_scene(mj: mujoco.MjSpec, description: RobotDescription, home: np.ndarray,
                    layout: WagonLayout = WagonLayout()) -> np.ndarray:
    """The ``wagon`` task's scene: a four-wheeled wagon in front of the robot, its handle at hand height; returns
    the wagon's home qpos (free joint, then the four wheels)."""
    bx, by, bz = layout.body_half_size
    r = layout.wheel_radius
    post_x = -bx - 0.015
    body_x = layout.handle_x - post_x
    chassis_z = r + bz
    wagon = mj.worldbody.add_body(name=WAGON_BODY, pos=(body_x, 0.0, chassis_z))
    wagon.add_freejoint(name=WAGON_BODY)
    blue = (0.2, 0.35, 0.75, 1.0)
    wagon.add_geom(name="wagon_bed", type=mujoco.mjtGeom.mjGEOM_BOX, size=(bx, by, bz), mass=layout.mass,
                   rgba=blue, contype=1, conaffinity=1)
    post_top = layout.handle_height - chassis_z
    for side in (1, -1):
        wagon.add_geom(name=f"wagon_post_{'left' if side > 0 else 'right'}", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                       fromto=(-bx, side * layout.handle_half_width * 0.9, 0.0,
                               post_x, side * layout.handle_half_width * 0.9, post_top),
                       size=(0.005, 0, 0), mass=0.01, rgba=(0.7, 0.7, 0.7, 1), contype=0, conaffinity=0)
    wagon.add_geom(name=WAGON_HANDLE_GEOM, type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                   fromto=(post_x, -layout.handle_half_width, post_top, post_x, layout.handle_half_width, post_top),
                   size=(0.008, 0, 0), mass=0.02, rgba=(0.9, 0.9, 0.9, 1), contype=1, conaffinity=1, condim=4,
                   # its priority gives the grip its contact parameters; the friction stays the pads'
                   priority=1, solref=layout.handle_solref, solimp=layout.handle_solimp,
                   friction=PAD_FRICTION)
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        wheel = wagon.add_body(name=f"wagon_wheel_{i}", pos=(sx * (bx - r), sy * (by + 0.01), r - chassis_z))
        wheel.add_joint(name=f"wagon_wheel_{i}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=(0, 1, 0), damping=1e-4)
        wheel.add_geom(name=f"wagon_wheel_{i}", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=(r, 0.008, 0),
                       quat=(0.7071068, 0.7071068, 0, 0), mass=0.02, rgba=(0.1, 0.1, 0.1, 1), contype=1,
                       conaffinity=1)
    return np.concatenate([[body_x, 0.0, chassis_z, 1.0, 0.0, 0.0, 0.0], np.zeros(4)])


def _add_grasp_sites_and_pads(mj: mujoco.MjSpec, description: RobotDescription) -> None:
    """The spec's finger collision boxes are bounding boxes of whole fingers that overlap even when the gripper
    is open, so they cannot pinch anything. Here they stop colliding, and each finger gets a thin pad whose inner
    face is at the closing axis' centre when the gripper is fully closed (the rack's travel from open)."""
    model = mj.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # qpos0: grippers fully open
    for side in SIDES:
        gripper = model.body(f"{side}_gripper")
        rot = data.xmat[gripper.id].reshape(3, 3)
        names = (f"{side}_gripper_finger_collision", f"{side}_gripper_finger_mirror_collision")
        centres = [data.geom(name).xpos.copy() for name in names]
        midpoint = (centres[0] + centres[1]) / 2
        mj.body(f"{side}_gripper").add_site(
            name=grasp_site(side), pos=(rot.T @ (midpoint - data.xpos[gripper.id])).tolist(), size=[0.004, 0, 0],
            rgba=(0.1, 0.9, 0.1, 0.6), group=4,
        )
        travel = rack_travel(description, f"{side}_gripper_drive")
        for name, centre, pad in zip(names, centres, finger_pads(side)):
            geom = mj.geom(name)
            geom.contype, geom.conaffinity = 0, 0
            finger = model.geom(name).bodyid[0]
            outward = 1.0 if rot[:, 2] @ (centre - midpoint) > 0 else -1.0
            pad_world = midpoint + rot @ np.array([0.0, -0.0005, outward * (travel + PAD_HALF_SIZE[2])])
            finger_rot = data.xmat[finger].reshape(3, 3)
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, (finger_rot.T @ rot).ravel())
            mj.body(model.body(finger).name).add_geom(
                name=pad, type=mujoco.mjtGeom.mjGEOM_BOX, size=PAD_HALF_SIZE,
                pos=(finger_rot.T @ (pad_world - data.xpos[finger])).tolist(), quat=quat.tolist(),
                rgba=(0.15, 0.15, 0.15, 1.0), friction=PAD_FRICTION, condim=4, contype=1, conaffinity=0,
                mass=0.0,
            )


def rack_travel(description: RobotDescription, drive: str) -> float:
    """Finger travel from open to closed, m: the rack's pitch radius times the drive's range."""
    rack = next(t for t in description.spec.transmissions if getattr(t, "drive", None) == drive)
    lo, hi = description.spec.joints[drive].range or (0.0, 0.0)
    return float(rack.pitch_radius * (hi - lo))  # type: ignore[union-attr]


def _add_workspace_camera(mj: mujoco.MjSpec) -> None:
    pos, target = np.array([0.3, -0.42, 0.36]), np.array([0.1, -0.1, 0.27])
    forward = (target - pos) / np.linalg.norm(target - pos)
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    cam = mj.worldbody.add_camera(name=WORKSPACE_CAMERA, pos=pos, fovy=50.0)
    cam.alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
    cam.alt.xyaxes = np.concatenate([right, np.cross(right, forward)]).tolist()


def place_cube(model: mujoco.MjModel, data: mujoco.MjData, xy: np.ndarray, yaw: float) -> None:
    """Put the cube at rest on the table at world (x, y) rotated by `yaw` (rad) about z; call mj_forward after."""
    joint = model.joint(CUBE_BODY)
    adr, dadr = joint.qposadr[0], joint.dofadr[0]
    z = data.qpos[adr + 2]
    data.qpos[adr : adr + 7] = [xy[0], xy[1], z, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    data.qvel[dadr : dadr + 6] = 0.0


def shift_wagon(model: mujoco.MjModel, data: mujoco.MjData, offset_xy: np.ndarray) -> None:
    """Move the wagon (at rest) by `offset_xy` (m) from where it stands; call mj_forward after."""
    joint = model.joint(WAGON_BODY)
    adr, dadr = joint.qposadr[0], joint.dofadr[0]
    data.qpos[adr : adr + 2] += offset_xy
    data.qvel[dadr : dadr + 6] = 0.0


class HandleHeight:
    """Raises or lowers the wagon handle of a compiled wagon scene by an offset from the layout's height (the
    posts that carry it follow); each `set` starts from the layout, so offsets do not add up. Call mj_forward
    after."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.handle = model.geom(WAGON_HANDLE_GEOM).id
        self.posts = [model.geom(f"wagon_post_{side}").id for side in SIDES]
        self.handle_z = float(model.geom_pos[self.handle, 2])
        self.post_ends = [self._ends(g) for g in self.posts]

    def _ends(self, geom: int) -> tuple[np.ndarray, np.ndarray]:
        """(bottom, top) of a capsule in its body's frame."""
        axis = np.zeros(9)
        mujoco.mju_quat2Mat(axis, self.model.geom_quat[geom])
        half = self.model.geom_size[geom, 1] * axis.reshape(3, 3)[:, 2]
        ends = sorted((self.model.geom_pos[geom] - half, self.model.geom_pos[geom] + half), key=lambda p: p[2])
        return ends[0].copy(), ends[1].copy()

    def set(self, offset: float) -> None:
        self.model.geom_pos[self.handle, 2] = self.handle_z + offset
        for geom, (bottom, top) in zip(self.posts, self.post_ends):
            top = top + np.array([0.0, 0.0, offset])
            quat = np.zeros(4)
            mujoco.mju_quatZ2Vec(quat, top - bottom)
            self.model.geom_pos[geom] = (bottom + top) / 2
            self.model.geom_quat[geom] = quat
            self.model.geom_size[geom, 1] = np.linalg.norm(top - bottom) / 2


class LightLevel:
    """Scales the scene's lights (every light's and the headlight's ambient and diffuse) from the model's own
    levels; each `set` starts from those, so scales do not multiply."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.lights = model.light_ambient.copy(), model.light_diffuse.copy()
        self.headlight = model.vis.headlight.ambient.copy(), model.vis.headlight.diffuse.copy()

    def set(self, scale: float) -> None:
        self.model.light_ambient[:] = scale * self.lights[0]
        self.model.light_diffuse[:] = scale * self.lights[1]
        self.model.vis.headlight.ambient[:] = scale * self.headlight[0]
        self.model.vis.headlight.diffuse[:] = scale * self.headlight[1]
