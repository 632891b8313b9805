"""`walk-zmp`: the ZMP pattern generator's leg targets plus torso attitude feedback from the IMU.

Feedback (gains in `AttitudeFeedback`): the torso's pitch and roll error (IMU orientation versus upright) shift the
ankle pitch/roll of the legs and the hip roll, which turns the feet against the tilt (an ankle strategy) and keeps
the torso level. Everything else is the generator's reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.locomotion.zmp_walk import WalkReference, ZMPWalk
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Observation, Robot


@dataclass(frozen=True)
class AttitudeFeedback:
    ankle_pitch: float = 0.0
    """rad of ankle pitch per rad of torso pitch."""
    ankle_roll: float = 0.0
    """rad of ankle roll per rad of torso roll."""
    hip_roll: float = 0.0
    """rad of hip roll per rad of torso roll."""


def tilt(quat: np.ndarray) -> tuple[float, float]:
    """(roll, pitch) of a w, x, y, z quaternion, rad (ZYX Euler angles)."""
    w, x, y, z = quat
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    return float(roll), float(pitch)


class WalkZMPPolicy(Policy):
    name = "walk-zmp"

    def __init__(self, robot: Robot, config: WalkConfig | None = None, feedback: AttitudeFeedback | None = None) -> None:
        super().__init__(robot)
        self.walk = ZMPWalk(config or WalkConfig(dt=robot.control_dt), robot.spec)
        if abs(self.walk.config.dt - robot.control_dt) > 1e-12:
            raise ValueError(f"walk dt {self.walk.config.dt} s must equal the control period {robot.control_dt} s")
        self.feedback = feedback or AttitudeFeedback()
        names = list(robot.joint_names)
        self._ankle_pitch = np.array([names.index(f"{s}_ankle_pitch") for s in ("left", "right")])
        self._ankle_roll = np.array([names.index(f"{s}_ankle_roll") for s in ("left", "right")])
        self._hip_roll = np.array([names.index(f"{s}_hip_roll") for s in ("left", "right")])
        self.last_reference: WalkReference | None = None

    def reset(self, obs: Observation) -> None:
        self._state = None

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        if self._state is None:
            self._state = self.walk.start(command)
        self._state, ref = self.walk.step(self._state, command)
        self.last_reference = ref
        q = ref.joint_pos.copy()
        roll, pitch = tilt(obs.imu_quat)
        fb = self.feedback
        q[self._ankle_pitch] += fb.ankle_pitch * pitch * np.array([1.0, -1.0])
        q[self._ankle_roll] += fb.ankle_roll * roll
        q[self._hip_roll] += fb.hip_roll * roll
        return self.joint_action(q)
