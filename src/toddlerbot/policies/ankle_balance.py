"""Ankle feedback while a motion stands on flat feet: the torso pitch the IMU measures against the pitch the motion's
joint angles imply with both soles flat on the floor, corrected at the ankles (toes pressed down when the robot
leans further forward than planned, heels when it leans back).

The implied pitch is forward kinematics: with the torso upright and the joints at a pose, each sole is tilted by
some pitch relative to its home (flat) orientation; the torso pitch that levels it is the opposite. It is tabulated
along the motion once, so a control step only interpolates.
"""

from __future__ import annotations

import mujoco
import numpy as np

from toddlerbot.policies.motions import Motion, full_pose
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.floor_pose import place_on_floor

GAIN = 0.5
"""rad of ankle correction per rad of torso pitch error."""
MAX_CORRECTION_RAD = np.deg2rad(15.0)
FLAT_FOOT_RANGE_RAD = np.deg2rad(50.0)
"""The feedback acts where the motion's implied torso pitch and the measured one are both within this of upright
(standing on the feet, not lying or on all fours)."""
TABLE_STEP_S = 0.05
ANKLES = ("left_ankle_pitch", "right_ankle_pitch")
FEET_PROBE_RAD = 0.01


class AnkleBalance:
    """Ankle-pitch corrections for one motion (`correction`)."""

    def __init__(self, description: RobotDescription, motion: Motion) -> None:
        self._kinematics = _SoleKinematics(description)
        self.times = np.arange(0.0, motion.duration + TABLE_STEP_S, TABLE_STEP_S)
        self.implied_pitch = np.array([self._kinematics.implied_pitch(full_pose(motion, description, t))
                                       for t in self.times])
        self._ankles = [description.joint_names.index(a) for a in ANKLES]
        self._toe_down = self._kinematics.toe_down_signs(self._ankles)
        self._n = description.n_motors

    def correction(self, t: float, pitch: float) -> np.ndarray:
        """Joint offsets (rad, `joint_names` order) at motion time ``t`` for a measured torso pitch (rad, > 0
        forward): zero away from standing on flat feet."""
        out = np.zeros(self._n)
        implied = float(np.interp(t, self.times, self.implied_pitch))
        if abs(implied) > FLAT_FOOT_RANGE_RAD or abs(pitch) > FLAT_FOOT_RANGE_RAD:
            return out
        offset = np.clip(GAIN * (pitch - implied), -MAX_CORRECTION_RAD, MAX_CORRECTION_RAD)
        out[self._ankles] = self._toe_down * offset
        return out


class _SoleKinematics:
    """The soles' tilt for a pose of the joints, with the torso upright (a scratch copy of the floating model)."""

    def __init__(self, description: RobotDescription) -> None:
        self.description = description
        self.model = description.model("floating", scene=True)
        self.data = mujoco.MjData(self.model)
        self._feet = [self.model.geom(g).id for g in description.handles.feet_geoms]
        self._home = self._sole_rotations(description.home_joint_pos)

    def _sole_rotations(self, joint_pos: np.ndarray) -> list[np.ndarray]:
        place_on_floor(self.model, self.data, self.description.transmission, joint_pos)
        return [self.data.geom_xmat[g].reshape(3, 3).copy() for g in self._feet]

    def sole_pitch(self, joint_pos: np.ndarray) -> float:
        """Mean pitch of the soles from their home orientation, rad (> 0: toes down)."""
        pitches = []
        for now, home in zip(self._sole_rotations(joint_pos), self._home, strict=True):
            relative = now @ home.T
            pitches.append(np.arctan2(relative[0, 2], relative[2, 2]))
        return float(np.mean(pitches))

    def implied_pitch(self, joint_pos: np.ndarray) -> float:
        """The torso pitch (rad, > 0 forward) that puts both soles flat at this pose."""
        return -self.sole_pitch(joint_pos)

    def toe_down_signs(self, ankles: list[int]) -> np.ndarray:
        """For each ankle joint, the sign of a change that turns its sole toes-down."""
        home = np.array(self.description.home_joint_pos)
        signs = []
        for k, ankle in enumerate(ankles):
            probe = home.copy()
            probe[ankle] += FEET_PROBE_RAD
            place_on_floor(self.model, self.data, self.description.transmission, probe)
            relative = self.data.geom_xmat[self._feet[k]].reshape(3, 3) @ self._home[k].T
            signs.append(np.sign(np.arctan2(relative[0, 2], relative[2, 2])))
        return np.array(signs)
