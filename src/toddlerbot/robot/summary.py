"""Figures of a compiled robot model: counts, mass, standing height, motor table."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

from toddlerbot.robot.builder import highest_point, lowest_point
from toddlerbot.robot.description import RobotDescription


@dataclass(frozen=True)
class MotorRow:
    id: int
    motor: str
    model: str
    joint: str
    group: str
    kp: int
    kd: int
    range: tuple[float, float]
    tau_max: float


@dataclass(frozen=True)
class ModelSummary:
    name: str
    bodies: int
    joints: int
    nq: int
    nv: int
    actuators: int
    equalities: int
    tendons: int
    geoms: int
    total_mass_kg: float
    standing_height_m: float
    torso_height_m: float
    motors: list[MotorRow]


def standing_height(model: mujoco.MjModel) -> float:
    """Top of the head minus the lowest sole point, at the home keyframe."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_kinematics(model, data)
    return highest_point(model, data) - lowest_point(model, data)


def summarize_model(description: RobotDescription, model: mujoco.MjModel) -> ModelSummary:
    """Counts and figures of `model` (one of the description's compiled models) and the description's motor table."""
    rows = []
    for motor, joint, catalogue_entry, limits in zip(description.motors, description.joint_names,
                                                     description.motor_models, description.motor_range, strict=True):
        rows.append(MotorRow(motor.id, motor.joint, catalogue_entry.name, joint, motor.group, motor.kp, motor.kd,
                             (float(limits[0]), float(limits[1])), catalogue_entry.actuator.tau_max))
    key = model.key("home")
    return ModelSummary(
        name=model.names[: model.names.index(b"\0")].decode() if model.names else description.spec.name,
        bodies=model.nbody - 1, joints=model.njnt, nq=model.nq, nv=model.nv, actuators=model.nu,
        equalities=model.neq, tendons=model.ntendon, geoms=model.ngeom,
        total_mass_kg=float(model.body_subtreemass[0]),
        standing_height_m=standing_height(model),
        torso_height_m=float(key.qpos[2]) if model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE else float("nan"),
        motors=rows,
    )
