"""Footstep planning on the floor plane from velocity commands.

Poses are (x, y, yaw) in the walk frame: origin at the midpoint of the feet at the start, x along the robot's
initial heading, z up. A "walk frame" pose P advances by the command over each step (one step = half a gait
cycle, increment applied in P's own heading), and the stance foot of step k sits half a stance width to its
side of P_k: left feet on +y, right feet on -y.
"""

from __future__ import annotations

import numpy as np

LEFT, RIGHT = 0, 1


def compose(pose: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """pose (+) delta: delta (dx, dy, dyaw) expressed in pose's frame."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.array([pose[0] + c * delta[0] - s * delta[1], pose[1] + s * delta[0] + c * delta[1], pose[2] + delta[2]])


def foot_pose(walk_pose: np.ndarray, side: int, stance_width: float) -> np.ndarray:
    """The foot of ``side`` (LEFT/RIGHT) beside a walk-frame pose."""
    return compose(walk_pose, np.array([0.0, stance_width / 2 if side == LEFT else -stance_width / 2, 0.0]))


def advance(walk_pose: np.ndarray, command: np.ndarray, step_time: float) -> np.ndarray:
    """Walk-frame pose one step later under a command (vx m/s, vy m/s, yaw rate rad/s) in the robot frame."""
    return compose(walk_pose, np.asarray(command, float) * step_time)


def stance_side(step: int, first_stance: int) -> int:
    """Side of the stance foot of step ``step`` (the first stance foot is ``first_stance``)."""
    return first_stance if step % 2 == 0 else 1 - first_stance
