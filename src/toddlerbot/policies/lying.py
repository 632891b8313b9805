"""How the torso lies, from the IMU's orientation alone (what the real robot knows): the world's up direction in the
torso frame, how upright the torso is, and which side it lies on.

The torso frame has x forward (the chest), y to the left and z up (to the head). Lying on the back the chest faces
up (up = +x), on the front down (up = -x); on its right side the left side faces up (up = +y).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

Lying = Literal["upright", "back", "front", "left side", "right side"]
SIDE_TOLERANCE_RAD = np.deg2rad(50.0)
"""A torso turned about its long axis this far or less from lying flat on its back or front counts as lying on it;
beyond, it lies on a side (and rolls before getting up)."""


def up_in_torso(imu_quat: np.ndarray) -> np.ndarray:
    """The world's up direction in the torso frame (the third row of the torso's rotation), for a (w, x, y, z)
    orientation."""
    w, x, y, z = imu_quat
    return np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])


def uprightness(imu_quat: np.ndarray) -> float:
    """z component of the torso's up axis in the world: 1 upright, 0 lying, -1 upside down."""
    return float(up_in_torso(imu_quat)[2])


def lying_on(imu_quat: np.ndarray, upright_at: float) -> Lying:
    """``upright`` when `uprightness` is at least ``upright_at``; otherwise the back, the front or a side, from the
    angle of the up direction about the torso's long axis (0 on the back, 180 deg on the front)."""
    up = up_in_torso(imu_quat)
    if up[2] >= upright_at:
        return "upright"
    turn = float(np.arctan2(up[1], up[0]))
    if abs(turn) <= SIDE_TOLERANCE_RAD:
        return "back"
    if abs(turn) >= np.pi - SIDE_TOLERANCE_RAD:
        return "front"
    return "right side" if turn > 0 else "left side"
