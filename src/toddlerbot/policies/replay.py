"""`replay`: play a keyframe motion (`toddlerbot.policies.motions`) on top of the home pose, then stop."""

from __future__ import annotations

import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.policies.motions import Motion
from toddlerbot.robot.interface import Observation, Robot


class ReplayPolicy(Policy):
    name = "replay"

    def __init__(self, robot: Robot, motion: Motion) -> None:
        super().__init__(robot)
        self.motion = motion
        names = list(robot.joint_names)
        self._index = np.array([names.index(j) for j in motion.joints])
        self._t = 0.0

    def reset(self, obs: Observation) -> None:
        self._t = 0.0

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        q = self.home_joint_pos.copy()
        q[self._index] = self.motion.at(self._t)
        self._t += self.control_dt
        return self.joint_action(q)

    @property
    def done(self) -> bool:
        return self._t > self.motion.duration + 1e-9
