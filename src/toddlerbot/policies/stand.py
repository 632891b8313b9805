"""`stand`: hold the spec's home pose."""

from __future__ import annotations

import numpy as np

from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation


class StandPolicy(Policy):
    name = "stand"

    def reset(self, obs: Observation) -> None:
        self._action = self.joint_action(self.home_joint_pos)

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        return self._action
