"""Which motors a manipulation task records, and the follower's compliant gains (appendix 8.12): shared by the
tasks, teleoperation and the diffusion policy, which must all agree on them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toddlerbot.robot.description import RobotDescription

UPPER_BODY_GROUPS = ("neck", "waist", "arm")
POLICY_HZ = 10
"""Rate of a manipulation episode's recorded observations and actions, and of the diffusion policy's steps, Hz
(appendix 8.12: the joint angles downsampled to 10 Hz for training)."""


@dataclass(frozen=True)
class ManipulationSpace:
    """Which motors make the recorded state and action vectors (the arms and grippers, motor-id order)."""

    indices: np.ndarray
    names: tuple[str, ...]

    @classmethod
    def of(cls, description: RobotDescription) -> ManipulationSpace:
        idx = np.concatenate([description.groups.get(g, np.zeros(0, dtype=int)) for g in ("arm", "gripper")])
        idx = np.sort(idx)
        return cls(idx, tuple(description.motor_names[i] for i in idx))

    @property
    def dim(self) -> int:
        return len(self.indices)


FOLLOWER_KP_SCALE = 0.5
"""Upper-body (neck, waist, arms) gains as a fraction of the spec's while demonstrations are collected (appendix
8.12: low gains, so the follower is compliant); policies trained on those demonstrations run at the same gains."""


def follower_gains(description: RobotDescription, upper_body_kp_scale: float = FOLLOWER_KP_SCALE) -> np.ndarray:
    """Firmware kp for the follower: the spec's gains, upper body (neck, waist, arms) scaled down so the arms
    give way on contact (appendix 8.12); grippers keep their current-limited spec gains."""
    if not 0 < upper_body_kp_scale <= 1:
        raise ValueError(f"upper_body_kp_scale must be in (0, 1], got {upper_body_kp_scale}")
    kp = description.default_kp.copy()
    for group in UPPER_BODY_GROUPS:
        idx = description.groups.get(group, np.zeros(0, dtype=int))
        kp[idx] = np.round(kp[idx] * upper_body_kp_scale)
    return kp
