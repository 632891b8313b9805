"""A policy with its upper body held at a pose: how a walking policy is checked to keep walking while the arms
hold a handle, carry or wave (`runtime.robustness`, the ``posed`` conditions)."""

from __future__ import annotations

import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation
from toddlerbot.robot.upper_body import upper_body_mask


class HeldUpperBody(Policy):
    """``inner``'s actions with the arm, gripper and neck targets replaced by ``pose`` (n_motors,) rad; the other
    motors, the gains and the command reach are the inner policy's."""

    def __init__(self, inner: Policy, pose: np.ndarray) -> None:
        super().__init__(inner.robot)
        description = inner.robot.description
        pose = np.asarray(pose, dtype=float)
        if pose.shape != (description.n_motors,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"upper-body pose: expected {description.n_motors} finite motor angles, got shape "
                             f"{pose.shape}")
        self.inner, self.pose = inner, pose
        self.mask = upper_body_mask(description)
        self.name, self.command_reach, self.needs_imu = inner.name, inner.command_reach, inner.needs_imu

    def reset(self, obs: Observation) -> None:
        self.inner.reset(obs)

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        action = self.inner.act(obs, command)
        targets = np.where(self.mask, self.pose, action.motor_targets)
        return Action(targets, self.transmission.motor_to_joint(targets), kp=action.kp, kd=action.kd)
