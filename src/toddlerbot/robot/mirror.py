"""The robot's left-right mirror: which motor mirrors which, with what sign, and how the IMU's vectors reflect.

ToddlerBot is symmetric about its sagittal plane (the world xz-plane of the model at its zero configuration, the
robot facing +x). Mirroring a state swaps each ``left_*`` motor with its ``right_*`` partner (a motor on the
midline is its own partner) and flips the sign where the partner's joint axis is the reflection of the motor's
with the opposite sense. Rotation axes are pseudo-vectors: reflecting y -> -y turns an axis (x, y, z) into
(-x, y, -z). The IMU's gravity direction (a vector) reflects with the plane's reflection in the IMU frame; its
angular velocity (a pseudo-vector) with the negated reflection.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.robot.description import RobotDescription

AXIS_TOLERANCE = 0.02
"""Largest |1 - |cos|| between a joint's reflected axis and its partner's for the two to mirror."""


@dataclass(frozen=True)
class Mirror:
    """Motor permutation and signs (``mirrored[i] = sign[i] * q[partner[i]]``) and the IMU frame's reflection."""

    partner: np.ndarray
    sign: np.ndarray
    imu_reflection: np.ndarray
    """3 x 3: a vector in the IMU frame, mirrored."""

    def motors(self, values, xp=np):
        """Mirror per-motor values (angles relative to a symmetric pose, speeds, targets' offsets) on the last axis."""
        return xp.asarray(self.sign) * values[..., self.partner]

    def gravity(self, vector, xp=np):
        return vector @ xp.asarray(self.imu_reflection).T

    def gyro(self, vector, xp=np):
        return -(vector @ xp.asarray(self.imu_reflection).T)


def partner_name(name: str) -> str:
    """``left_x`` <-> ``right_x``; a name on the midline is its own partner."""
    for side, other in (("left_", "right_"), ("right_", "left_")):
        if name.startswith(side):
            return other + name.removeprefix(side)
    return name


def mirror_partners(description: RobotDescription, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(partner index, sign) of each named joint of the model (joints or motors: a motor is the joint it turns),
    from the axes at the zero configuration; a clear error names the joint without a partner or a mirrored axis."""
    return _partners(*_zero_pose(description), names)


def _partners(model: mujoco.MjModel, data: mujoco.MjData, names) -> tuple[np.ndarray, np.ndarray]:
    names = list(names)
    partner, sign = np.arange(len(names)), np.ones(len(names))
    for i, name in enumerate(names):
        other = partner_name(name)
        if other not in names:
            raise ToddlerbotError(f"robot mirror: motor {name} has no partner {other}")
        partner[i] = names.index(other)
        axis, other_axis = (data.xaxis[_joint_id(model, n)] for n in (name, other))
        cos = float(np.array([-axis[0], axis[1], -axis[2]]) @ other_axis)
        if abs(1.0 - abs(cos)) > AXIS_TOLERANCE:
            raise ToddlerbotError(f"robot mirror: the axes of {name} and {other} are not mirror images "
                                  f"(cos {cos:.3f}; expected +-1)")
        sign[i] = np.sign(cos)
    return partner, sign


def robot_mirror(description: RobotDescription) -> Mirror:
    """The description's mirror over its motors, checked: every motor has a partner whose axis reflects onto its
    own and the home pose is its own mirror (a clear error names the motor where the robot is not symmetric)."""
    names = description.motor_names
    model, data = _zero_pose(description)
    partner, sign = _partners(model, data, names)
    home = np.asarray(description.home_motor_pos)
    if not np.allclose(sign * home[partner], home, atol=1e-6):
        worst = names[int(np.argmax(np.abs(sign * home[partner] - home)))]
        raise ToddlerbotError(f"robot mirror: the home pose is not symmetric at {worst}")
    to_world = data.site_xmat[model.site(description.handles.imu_site).id].reshape(3, 3)
    return Mirror(partner, sign, to_world.T @ np.diag([1.0, -1.0, 1.0]) @ to_world)


def _zero_pose(description: RobotDescription) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The model and its kinematics at the zero configuration, where the robot is symmetric about y = 0."""
    model = description.model()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return model, data


def _joint_id(model: mujoco.MjModel, name: str) -> int:
    joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if joint < 0:
        raise ToddlerbotError(f"robot mirror: motor {name} has no joint of that name in the model")
    return joint
