"""Swing-foot trajectories: minimum-jerk travel on the floor plane and a smooth lift-off/touch-down bump."""

from __future__ import annotations

import numpy as np


def min_jerk(s: float) -> float:
    """Minimum-jerk blend 0 -> 1 for s in [0, 1] (zero velocity and acceleration at both ends)."""
    s = min(max(s, 0.0), 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s)


def swing_pose(start: np.ndarray, end: np.ndarray, s: float, height: float) -> tuple[np.ndarray, float]:
    """Foot (x, y, z) and yaw at swing phase s in [0, 1] from floor pose ``start`` to ``end`` ((x, y, yaw) each)."""
    b = min_jerk(s)
    xy = start[:2] + b * (end[:2] - start[:2])
    dyaw = (end[2] - start[2] + np.pi) % (2 * np.pi) - np.pi
    z = height * 0.5 * (1.0 - np.cos(2.0 * np.pi * min(max(s, 0.0), 1.0)))
    return np.array([xy[0], xy[1], z]), float(start[2] + b * dyaw)
