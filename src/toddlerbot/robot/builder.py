"""Build the MuJoCo model of a robot spec with MuJoCo's model-editing API (mujoco.MjSpec).

The result is deterministic: the same spec and options give a byte-identical MJCF.

* Bodies carry the spec's inertials; motor joints take damping, armature and friction loss from the motor
  catalogue; every motor gets a torque actuator (ctrl = N*m at the motor joint), limited to its braking torque.
* Transmissions: spur gears and racks are joint equalities, the waist differential is two limited fixed
  tendons (range = backlash), parallel linkages are closed by weld equalities (relative pose from qpos0).
* Robot geoms collide with the floor only (contype 1 / conaffinity 0 against a floor with contype 0 /
  conaffinity 1), plus the spec's explicit self-collision pairs. They are in `COLLISION_GROUP`; the visual
  geometry (`toddlerbot.robot.visuals`: motor housings, printed shells, camera lens, gripper jaws) is in
  `VISUAL_GROUP` and has no contacts and no mass.
* IMU sensors (orientation, gyro, accelerometer, velocimeter) at the ``imu`` site, when it exists.
* A ``home`` keyframe: the spec's home pose, the motors and linkage rods derived through the transmissions,
  and (floating base) the torso raised so the lowest sole point touches z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from toddlerbot.actuation.catalogue import Catalogue, default_catalogue
from toddlerbot.robot.spec import (
    BevelDifferential,
    ParallelLinkage,
    RackAndPinion,
    RobotSpec,
    SpurGear,
)
from toddlerbot.robot.transmission import TransmissionMap, build_transmission_map
from toddlerbot.robot.visuals import FINISHES, VISUAL_GROUP, visual_geoms

Base = Literal["floating", "fixed"]
FREEJOINT = "floating_base"
IMU_SITE = "imu"

_GEOM_TYPES = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
}
_INTEGRATORS = {
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
}
_SOLVERS = {"Newton": mujoco.mjtSolver.mjSOL_NEWTON, "CG": mujoco.mjtSolver.mjSOL_CG, "PGS": mujoco.mjtSolver.mjSOL_PGS}
_CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}
_ROBOT_RGBA = (0.85, 0.55, 0.2, 1.0)
COLLISION_GROUP = 2
"""Geom group of the robot's collision primitives: drawn by default (the head camera sees them, as it always has),
left out by scene renders, which draw `VISUAL_GROUP` instead."""
SKELETON_GROUP = 1
_SKELETON_RADIUS = 0.007
_SKELETON_MIN_LENGTH = 0.01

# Scene cameras (position, xyaxes), all tracking the robot's centre of mass.
_SCENE_CAMERAS = {
    "perspective": ((0.7, -0.7, 0.7), (1, 1, 0, -1, 1, 3)),
    "side": ((0.0, -1.0, 0.6), (1, 0, 0, 0, 1, 3)),
    "front": ((1.0, 0.0, 0.6), (0, 1, 0, -1, 0, 3)),
    "top": ((0.0, 0.0, 1.0), (0, 1, 0, -1, 0, 0)),
}


@dataclass(frozen=True)
class BuildOptions:
    base: Base = "floating"
    scene: bool = False


def build_mjspec(
    spec: RobotSpec,
    base: Base = "floating",
    scene: bool = False,
    catalogue: Catalogue | None = None,
    transmission: TransmissionMap | None = None,
    visuals: bool = True,
) -> mujoco.MjSpec:
    """An MjSpec of the robot, already compiled once (write it with ``.to_xml()``)."""
    return compile_robot(spec, base, scene, catalogue, transmission, visuals)[0]


def build_model(
    spec: RobotSpec, base: Base = "floating", scene: bool = False, catalogue: Catalogue | None = None,
    visuals: bool = True,
) -> mujoco.MjModel:
    """Compile the robot's model; consumers that have a `RobotDescription` use its cached `model()` instead."""
    return compile_robot(spec, base, scene, catalogue, visuals=visuals)[1]


def compile_robot(
    spec: RobotSpec,
    base: Base = "floating",
    scene: bool = False,
    catalogue: Catalogue | None = None,
    transmission: TransmissionMap | None = None,
    visuals: bool = True,
) -> tuple[mujoco.MjSpec, mujoco.MjModel]:
    """The robot's MjSpec and its model, compiled once (the home keyframe is filled in on both).

    `RobotDescription` passes its catalogue and transmission map; standalone callers get the packaged catalogue
    and a map built from `spec`. ``visuals=False`` leaves the visual geometry out (physics is the same either
    way; a model that is never rendered, such as MJX training's, saves their kinematics)."""
    catalogue = catalogue or default_catalogue()
    transmission = transmission or build_transmission_map(spec)
    mj = mujoco.MjSpec()
    mj.modelname = spec.name if spec.variant is None else f"{spec.name}_{spec.variant}"
    mj.compiler.degree = False
    mj.compiler.autolimits = True
    _set_options(mj, spec)
    motor_params = {m.joint: catalogue[m.model].actuator for m in spec.motors}

    bodies = {"world": mj.worldbody}
    for body in spec.bodies:
        b = bodies[body.parent].add_body(name=body.name, pos=body.pos, quat=body.quat)
        b.mass, b.ipos, b.iquat, b.inertia = body.mass, body.com, body.inertia_quat, body.inertia
        b.explicitinertial = True
        bodies[body.name] = b
        if body.parent == "world" and base == "floating":
            b.add_freejoint(name=FREEJOINT)
        if body.joint is not None:
            j = body.joint
            dyn = motor_params.get(j.name)
            b.add_joint(
                name=j.name,
                type=mujoco.mjtJoint.mjJNT_HINGE if j.type == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE,
                axis=j.axis,
                pos=j.pos,
                range=j.range or (0.0, 0.0),
                limited=mujoco.mjtLimited.mjLIMITED_TRUE if j.range else mujoco.mjtLimited.mjLIMITED_FALSE,
                damping=[dyn.damping if dyn else j.damping],
                armature=dyn.armature if dyn else j.armature,
                frictionloss=dyn.frictionloss if dyn else j.frictionloss,
            )
        for g in body.collision:
            b.add_geom(
                name=g.name, type=_GEOM_TYPES[g.type], size=_pad3(g.size), pos=g.pos, quat=g.quat,
                contype=1, conaffinity=0, rgba=_ROBOT_RGBA, group=COLLISION_GROUP,
            )
        for s in body.sites:
            b.add_site(name=s.name, pos=s.pos, quat=s.quat, size=[0.005, 0, 0], rgba=(0.2, 0.6, 1.0, 0.5), group=4)
        for c in body.cameras:
            b.add_camera(name=c.name, pos=c.pos, quat=c.quat, fovy=c.fovy)

    _add_skeleton(mj, spec)
    if visuals:
        _add_visuals(mj, spec, catalogue)
    _add_transmissions(mj, spec)
    for g1, g2 in spec.contacts.self_pairs:
        mj.add_pair(geomname1=g1, geomname2=g2)
    for motor in spec.motors_by_id:
        limit = motor_params[motor.joint].tau_brake
        act = mj.add_actuator(name=motor.joint, target=motor.joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_motor()
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = (-limit, limit)
    if any(s.name == IMU_SITE for b in spec.bodies for s in b.sites):
        _add_imu_sensors(mj)
    if scene:
        _add_scene(mj)
    model = _compile_with_home_key(mj, base, transmission, home_joint_pos(spec, transmission))
    return mj, model


def build_xml(spec: RobotSpec, base: Base = "floating", scene: bool = False) -> str:
    return build_mjspec(spec, base, scene).to_xml()


def _pad3(size: list[float]) -> list[float]:
    return list(size) + [0.0] * (3 - len(size))


def _add_skeleton(mj: mujoco.MjSpec, spec: RobotSpec) -> None:
    """Visual-only capsules from each body to its children, so links without collision geoms are drawn.

    They have no mass (bodies carry explicit inertials) and never collide (contype = conaffinity = 0).
    """
    for body in spec.bodies:
        if body.parent == "world" or np.linalg.norm(body.pos) < _SKELETON_MIN_LENGTH:
            continue
        mj.body(body.parent).add_geom(
            name=f"{body.name}_link_visual", type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=(0, 0, 0, *body.pos),
            size=(_SKELETON_RADIUS, 0, 0), contype=0, conaffinity=0, group=SKELETON_GROUP,
            rgba=(0.35, 0.35, 0.38, 1.0),
        )


def _add_visuals(mj: mujoco.MjSpec, spec: RobotSpec, catalogue: Catalogue) -> None:
    """The visual geometry: no contacts, no mass (every body has an explicit inertial), its own group."""
    for name, finish in FINISHES.items():
        mj.add_material(name=f"visual_{name}", emission=finish.emission, specular=finish.specular,
                        shininess=finish.shininess)
    for v in visual_geoms(spec, catalogue):
        mj.body(v.body).add_geom(
            name=v.name, type=_GEOM_TYPES[v.type], size=v.size, pos=v.pos, quat=v.quat, rgba=v.rgba,
            material=f"visual_{v.finish}", contype=0, conaffinity=0, group=VISUAL_GROUP,
        )


def _set_options(mj: mujoco.MjSpec, spec: RobotSpec) -> None:
    sim = spec.simulation
    mj.option.timestep = sim.timestep
    mj.option.integrator = _INTEGRATORS[sim.integrator]
    mj.option.solver = _SOLVERS[sim.solver]
    mj.option.iterations = sim.iterations
    mj.option.ls_iterations = sim.ls_iterations
    mj.option.cone = _CONES[sim.cone]


def _add_transmissions(mj: mujoco.MjSpec, spec: RobotSpec) -> None:
    solref, solimp = spec.constraints.solref, spec.constraints.solimp

    def joint_equality(driven: str, drive: str, coef: float) -> None:
        mj.add_equality(
            name=f"{driven}_coupling", type=mujoco.mjtEq.mjEQ_JOINT, name1=driven, name2=drive,
            objtype=mujoco.mjtObj.mjOBJ_JOINT, data=[0.0, coef] + [0.0] * 10, solref=solref, solimp=solimp,
        )

    for t in spec.transmissions:
        if isinstance(t, SpurGear):
            joint_equality(t.driven, t.drive, -t.ratio)
        elif isinstance(t, RackAndPinion):
            for finger in t.driven:
                joint_equality(finger, t.drive, -t.pitch_radius)
        elif isinstance(t, ParallelLinkage):
            for pair in t.rods:
                # zero relative-pose quaternion: MuJoCo takes the relative pose from qpos0
                mj.add_equality(
                    name=f"{pair.rod}_loop", type=mujoco.mjtEq.mjEQ_WELD, name1=pair.rod, name2=pair.bearing,
                    objtype=mujoco.mjtObj.mjOBJ_BODY, data=[0.0] * 10 + [1.0, 0.0], solref=solref, solimp=solimp,
                )
        elif isinstance(t, BevelDifferential):
            m1, m2 = t.drives
            for output, coefs, backlash in (
                (t.roll, (t.roll_coef, -t.roll_coef), t.roll_backlash),
                (t.yaw, (-t.yaw_coef, -t.yaw_coef), t.yaw_backlash),
            ):
                tendon = mj.add_tendon(name=f"{output}_coupling", limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                                       range=(-backlash, backlash))
                tendon.wrap_joint(m1, coefs[0])
                tendon.wrap_joint(m2, coefs[1])
                tendon.wrap_joint(output, 1.0)


def _add_imu_sensors(mj: mujoco.MjSpec) -> None:
    site = mujoco.mjtObj.mjOBJ_SITE
    for name, kind in (
        ("imu_quat", mujoco.mjtSensor.mjSENS_FRAMEQUAT),
        ("imu_gyro", mujoco.mjtSensor.mjSENS_GYRO),
        ("imu_accel", mujoco.mjtSensor.mjSENS_ACCELEROMETER),
        ("imu_vel", mujoco.mjtSensor.mjSENS_VELOCIMETER),
        ("imu_pos", mujoco.mjtSensor.mjSENS_FRAMEPOS),
    ):
        mj.add_sensor(name=name, type=kind, objtype=site, objname=IMU_SITE)


def _add_scene(mj: mujoco.MjSpec) -> None:
    mj.add_texture(
        name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=(0.2, 0.3, 0.4), rgb2=(0.1, 0.2, 0.3), mark=mujoco.mjtMark.mjMARK_EDGE, markrgb=(0.8, 0.8, 0.8),
        width=300, height=300,
    )
    material = mj.add_material(name="grid", texrepeat=(8, 8), reflectance=0.1)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    mj.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=(0, 0, 0.05), material="grid", contype=0, conaffinity=1,
    )
    mj.worldbody.add_light(name="sun", pos=(0, 0, 1.5), dir=(0, 0, -1), type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    for name, (pos, xyaxes) in _SCENE_CAMERAS.items():
        cam = mj.worldbody.add_camera(name=name, pos=pos, mode=mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM)
        cam.alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
        cam.alt.xyaxes = xyaxes
    mj.stat.center = (0, 0, 0.25)
    mj.stat.extent = 0.6
    mj.visual.global_.offwidth = 1280
    mj.visual.global_.offheight = 720


def home_qpos(model: mujoco.MjModel, transmission: TransmissionMap, home_joint_pos: np.ndarray) -> np.ndarray:
    """qpos of a home pose (output-joint positions in ``transmission.joint_names`` order, rad or m) with the base at
    the spec's zero-pose height (before dropping to the floor); motors and linkage rods follow the transmissions."""
    qpos = model.qpos0.copy()
    motor_pos = transmission.joint_to_motor(np.asarray(home_joint_pos, dtype=float))
    for name, value in transmission.motor_to_model(motor_pos).items():
        qpos[model.joint(name).qposadr[0]] = value
    return qpos


def home_joint_pos(spec: RobotSpec, transmission: TransmissionMap) -> np.ndarray:
    """The spec's home pose in output-joint space (``transmission.joint_names`` order; unlisted joints at 0)."""
    return np.array([spec.home.get(name, 0.0) for name in transmission.joint_names])


def lowest_point(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Lowest z of any robot collision geom (boxes by their corners, round geoms by their extent)."""
    return min(geom_z_extent(model, data, g)[0] for g in _collision_geoms(model))


def highest_point(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    return max(geom_z_extent(model, data, g)[1] for g in _collision_geoms(model))


def _collision_geoms(model: mujoco.MjModel) -> list[int]:
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0 and model.geom_contype[g]]


def geom_z_extent(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> tuple[float, float]:
    size, z, rot = model.geom_size[geom], data.geom_xpos[geom][2], data.geom_xmat[geom].reshape(3, 3)
    kind = model.geom_type[geom]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        half = float(np.abs(rot[2]) @ size)
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        half = float(size[0])
    elif kind in (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER):
        half = float(abs(rot[2, 2]) * size[1] + (size[0] if kind == mujoco.mjtGeom.mjGEOM_CAPSULE else
                                                  size[0] * np.hypot(rot[2, 0], rot[2, 1])))
    else:
        raise ValueError(f"geom {geom}: unsupported type {kind}")
    return z - half, z + half


def _compile_with_home_key(
    mj: mujoco.MjSpec, base: Base, transmission: TransmissionMap, joint_pos: np.ndarray
) -> mujoco.MjModel:
    """Compile once with a placeholder ``home`` key, then write the home qpos (it needs the compiled qpos0 and, on a
    floating base, the lowest sole point) into both the model and the spec."""
    key = mj.add_key(name="home")
    model = mj.compile()
    data = mujoco.MjData(model)
    data.qpos[:] = home_qpos(model, transmission, joint_pos)
    if base == "floating":
        mujoco.mj_kinematics(model, data)
        data.qpos[2] -= lowest_point(model, data)
    key.qpos = data.qpos.tolist()
    model.key_qpos[model.key("home").id] = data.qpos
    return model
