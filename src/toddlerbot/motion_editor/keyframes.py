"""The motion being edited: a list of full-body keyframes with a duration each, and its motion-YAML text.

A keyframe holds every output joint (rad, `RobotDescription.joint_names` order) and, optionally, where the torso is
(a `BasePose`: lying on the back or front, or any roll and pitch; None: standing upright). Its duration is the
time, s, taken to reach it from the keyframe before (the first keyframe is at t = 0, duration 0). Reordering moves
poses (with their base poses) between positions and leaves the durations where they are, so the motion's timing
stays the same.

On save, the motion lists the joints it had when loaded plus every joint that leaves the home pose in some
keyframe; angles are written in degrees with 0.01 deg resolution, and the text is checked with
`toddlerbot.policies.motions.parse_motion` before it is written, exactly as `sim run --policy replay` reads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import yaml

from toddlerbot.policies.motions import INTERPOLATIONS, BasePose, Motion, MotionError, parse_motion
from toddlerbot.robot.description import RobotDescription

MIN_DURATION_S = 0.05
"""Shortest transition between keyframes, s (2.5 control steps at 50 Hz)."""
MAX_DURATION_S = 60.0
DEFAULT_DURATION_S = 1.0
CHANGED_RAD = np.deg2rad(0.05)
"""A joint this far from home in some keyframe is written into the motion."""


@dataclass
class Keyframes:
    """An editable motion; every method keeps it valid (>= 2 keyframes, durations in range, angles in range)."""

    description: RobotDescription
    poses: list[np.ndarray]
    """Keyframe poses, (n_joints,) rad each."""
    durations: list[float]
    """durations[i]: s from keyframe i-1 to keyframe i; durations[0] is 0."""
    name: str = "motion"
    text: str = ""
    """The motion's one-line description."""
    interpolation: str = "smooth"
    listed: tuple[str, ...] = field(default_factory=tuple)
    """Joints the loaded motion listed (kept on save even if they stay at home)."""
    bases: list[BasePose | None] = field(default_factory=list)
    """Each keyframe's base pose (None: upright); empty at construction means none gives one."""

    def __post_init__(self) -> None:
        if not self.bases:
            self.bases = [None] * len(self.poses)

    # -- construction -----------------------------------------------------------------------------------------
    @classmethod
    def new(cls, description: RobotDescription, name: str = "motion") -> Keyframes:
        """Two keyframes at the home pose, one second apart."""
        home = np.array(description.home_joint_pos)
        return cls(description, [home.copy(), home.copy()], [0.0, DEFAULT_DURATION_S], name=name)

    @classmethod
    def from_motion(cls, motion: Motion, description: RobotDescription, text: str = "") -> Keyframes:
        names = list(description.joint_names)
        index = [names.index(j) for j in motion.joints]
        poses = []
        for row in motion.poses:
            pose = np.array(description.home_joint_pos)
            pose[index] = row
            poses.append(pose)
        durations = [0.0, *np.diff(motion.times).tolist()]
        return cls(description, poses, durations, name=motion.name, text=text, interpolation=motion.interpolation,
                   listed=motion.joints, bases=list(motion.bases))

    # -- queries ----------------------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.poses)

    @property
    def times(self) -> np.ndarray:
        """Keyframe times, s."""
        return np.cumsum(self.durations)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.description.joint_names

    def joint_index(self, joint: str) -> int:
        try:
            return self.joint_names.index(joint)
        except ValueError:
            raise MotionError(f"unknown joint {joint!r}") from None

    # -- edits ------------------------------------------------------------------------------------------------
    def set_joint(self, i: int, joint: str, rad: float) -> float:
        """Set one joint of keyframe i (clamped to the joint's range); returns the value set, rad."""
        j = self.joint_index(joint)
        lo, hi = self.description.joint_range[j]
        value = float(np.clip(rad, lo, hi))
        self.poses[self._check(i)][j] = value
        return value

    def set_pose(self, i: int, pose: np.ndarray) -> None:
        rng = self.description.joint_range
        self.poses[self._check(i)] = np.clip(np.asarray(pose, dtype=float), rng[:, 0], rng[:, 1])

    def set_base(self, i: int, base: BasePose | None) -> None:
        """Where the torso is at keyframe i (None: standing upright)."""
        self.bases[self._check(i)] = base

    def insert_after(self, i: int) -> int:
        """A copy of keyframe i right after it (duration: that of keyframe i, or 1 s after the first); returns the
        new keyframe's index."""
        self._check(i)
        duration = self.durations[i] if i > 0 else DEFAULT_DURATION_S
        self.poses.insert(i + 1, self.poses[i].copy())
        self.bases.insert(i + 1, self.bases[i])
        self.durations.insert(i + 1, duration)
        return i + 1

    def delete(self, i: int) -> int:
        """Remove keyframe i (a motion keeps at least two); returns the index to select next."""
        self._check(i)
        if len(self) <= 2:
            raise MotionError("a motion needs at least two keyframes: add one before deleting this one")
        del self.poses[i]
        del self.bases[i]
        del self.durations[i]
        self.durations[0] = 0.0
        return min(i, len(self) - 1)

    def move(self, i: int, step: int) -> int:
        """Move keyframe i's pose `step` places (-1 earlier, +1 later); durations stay in place. Returns its new
        index (unchanged at either end)."""
        self._check(i)
        k = i + step
        if not 0 <= k < len(self):
            return i
        self.poses[i], self.poses[k] = self.poses[k], self.poses[i]
        self.bases[i], self.bases[k] = self.bases[k], self.bases[i]
        return k

    def set_duration(self, i: int, seconds: float) -> None:
        if self._check(i) == 0:
            raise MotionError("the first keyframe is at t = 0 s; set the duration of a later keyframe")
        if not (math.isfinite(seconds) and MIN_DURATION_S <= seconds <= MAX_DURATION_S):
            raise MotionError(f"duration {seconds:g} s: expected {MIN_DURATION_S:g}-{MAX_DURATION_S:g} s")
        self.durations[i] = float(seconds)

    def _check(self, i: int) -> int:
        if not 0 <= i < len(self):
            raise MotionError(f"no keyframe {i}: the motion has keyframes 0-{len(self) - 1}")
        return i

    # -- output -----------------------------------------------------------------------------------------------
    def saved_joints(self) -> list[str]:
        """Joints the saved motion lists: the loaded ones plus every joint moved from home, in spec order."""
        home = np.asarray(self.description.home_joint_pos)
        moved = np.any(np.abs(np.stack(self.poses) - home) > CHANGED_RAD, axis=0)
        return [j for k, j in enumerate(self.joint_names) if moved[k] or j in self.listed]

    def to_raw(self) -> dict:
        """The motion as the YAML mapping `parse_motion` reads (degrees, seconds)."""
        joints = self.saved_joints() or [self.joint_names[0]]
        rng = self.description.joint_range
        frames = []
        for t, pose, base in zip(np.round(self.times, 3), self.poses, self.bases, strict=True):
            frame: dict[str, object] = {"t": float(t)}
            if base is not None:
                frame["base"] = base_raw(base)
            for j in joints:
                k = self.joint_names.index(j)
                frame[j] = _degrees(pose[k], *rng[k])
            frames.append(frame)
        raw = {"name": self.name, "description": self.text, "interpolation": self.interpolation, "joints": joints,
               "keyframes": frames}
        if not raw["description"]:
            del raw["description"]
        return raw

    def to_motion(self, source: str) -> Motion:
        """The motion as it will be saved, validated (`MotionError` naming `source` otherwise)."""
        if self.interpolation not in INTERPOLATIONS:
            raise MotionError(f"{source}: interpolation {self.interpolation!r} is not one of "
                              f"{', '.join(INTERPOLATIONS)}")
        return parse_motion(self.to_raw(), self.description, source)

    def to_yaml(self) -> str:
        """Motion YAML in the packaged motions' style: one flow-style line per keyframe."""
        raw = self.to_raw()

        def flow(value: object) -> str:
            return yaml.safe_dump(value, default_flow_style=True, width=1 << 20, sort_keys=False).strip()

        def scalar(value: str) -> str:
            return yaml.safe_dump(value, width=1 << 20).removesuffix("\n...\n").strip()

        lines = ["# Written by `toddlerbot motion edit`. Angles in degrees (output joints), times in seconds;",
                 "# joints not listed hold the home pose.", f"name: {scalar(raw['name'])}"]
        if "description" in raw:
            lines.append(f"description: {scalar(raw['description'])}")
        lines += [f"interpolation: {raw['interpolation']}", f"joints: {flow(raw['joints'])}", "keyframes:"]
        lines += [f"  - {flow(frame)}" for frame in raw["keyframes"]]
        return "\n".join(lines) + "\n"


def base_raw(base: BasePose) -> dict[str, float]:
    """A base pose as the format writes it: roll and pitch in degrees to 0.01 deg, z in m to 0.1 mm if given."""
    raw = {"roll": round(float(np.rad2deg(base.roll)), 2), "pitch": round(float(np.rad2deg(base.pitch)), 2)}
    if base.z is not None:
        raw["z"] = round(base.z, 4)
    return raw


def _degrees(rad: float, lo: float, hi: float) -> float:
    """`rad` in degrees to 0.01 deg, still inside [lo, hi] rad as `parse_motion` checks it (1e-9 rad slack)."""
    deg = round(float(np.rad2deg(rad)), 2)
    if np.deg2rad(deg) > hi + 1e-9:
        deg = math.floor(np.rad2deg(hi) * 100) / 100
    elif np.deg2rad(deg) < lo - 1e-9:
        deg = math.ceil(np.rad2deg(lo) * 100) / 100
    return deg
