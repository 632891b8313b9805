"""The upper body a walking policy must keep walking under (arms, grippers, neck) and random poses of it: a handle
held, a load carried, a wave. One definition for the RL environment's randomisation (JAX) and the simulator's
robustness trials (numpy)."""

from __future__ import annotations

import numpy as np

from toddlerbot.robot.description import RobotDescription

UPPER_BODY_GROUPS = ("arm", "gripper", "neck")
"""Motor groups whose pose a walking policy must tolerate (`RandomizationConfig.upper_body_pose`); the waist
moves the torso itself and stays at home."""


def upper_body_mask(description: RobotDescription) -> np.ndarray:
    """(n_motors,) True for the robot's arm, gripper and neck motors."""
    mask = np.zeros(description.n_motors, dtype=bool)
    for group in UPPER_BODY_GROUPS:
        mask[list(description.groups.get(group, ()))] = True
    return mask


def upper_body_offsets(u, fraction: float, home, motor_range, mask, xp=np):
    """(n_motors,) offsets from home of an upper-body pose: ``u`` in [-1, 1] per motor is how far towards its
    upper (u > 0) or lower limit, in ``fraction``s of the way there; motors outside ``mask``, and those without a
    finite limit, stay at home (numpy or ``xp=jax.numpy``)."""
    room = xp.where(u > 0, motor_range[:, 1] - home, home - motor_range[:, 0])
    room = xp.where(xp.isfinite(room), room, 0.0)
    return xp.where(mask, fraction * u * room, 0.0)


def random_upper_body_pose(description: RobotDescription, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """(n_motors,) motor targets: home, with each upper-body motor drawn uniformly between home and ``fraction`` of
    the way to either limit."""
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"upper-body pose fraction {fraction}: expected a fraction of the range in [0, 1]")
    home = np.asarray(description.home_motor_pos, dtype=float)
    u = rng.uniform(-1.0, 1.0, description.n_motors)
    return home + upper_body_offsets(u, fraction, home, np.asarray(description.motor_range, dtype=float),
                                     upper_body_mask(description))
