"""A pose placed on the floor: output-joint angles with the torso tilted by a roll and a pitch, either resting on the
floor (its lowest collision point at z = 0) or with the torso frame at a given height. The motion editor draws
keyframes this way, and a simulation of a motion that starts lying down starts from it.

Angles follow the IMU's attitude: pitch > 0 leans the torso forward, so lying on the back is pitch -pi/2 and lying
on the front +pi/2; roll > 0 tips it onto its right side.
"""

from __future__ import annotations

import mujoco
import numpy as np

from toddlerbot.robot.builder import FREEJOINT, home_qpos, lowest_point
from toddlerbot.robot.transmission import TransmissionMap


def tilt_quat(roll: float, pitch: float) -> np.ndarray:
    """Orientation (w, x, y, z) of a torso pitched about the world's y axis after rolling about its own x axis."""
    qx = np.array([np.cos(roll / 2), np.sin(roll / 2), 0.0, 0.0])
    qy = np.array([np.cos(pitch / 2), 0.0, np.sin(pitch / 2), 0.0])
    out = np.empty(4)
    mujoco.mju_mulQuat(out, qy, qx)
    return out


def place_on_floor(model: mujoco.MjModel, data: mujoco.MjData, transmission: TransmissionMap, joint_pos: np.ndarray,
                   roll: float = 0.0, pitch: float = 0.0, z: float | None = None) -> mujoco.MjData:
    """Set ``data`` (of the floating model) to ``joint_pos`` (rad, ``transmission.joint_names`` order) with the torso
    tilted by ``roll`` and ``pitch`` (rad), its frame ``z`` m high, or resting on the floor when
    ``z`` is None; positions computed (`mj_kinematics`). Returns ``data``."""
    base = model.joint(FREEJOINT).qposadr[0]
    data.qpos[:] = home_qpos(model, transmission, joint_pos)
    data.qpos[base + 3 : base + 7] = tilt_quat(roll, pitch)
    mujoco.mj_kinematics(model, data)
    data.qpos[base + 2] = data.qpos[base + 2] - lowest_point(model, data) if z is None else z
    mujoco.mj_kinematics(model, data)
    return data
