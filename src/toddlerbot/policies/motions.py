"""Keyframe motions: a human-editable YAML format, validated against the robot description, interpolated in time.

Format (angles in degrees, times in seconds; see ``motions/*.yaml``)::

    name: wave
    description: wave the right hand
    interpolation: smooth        # smooth (cubic ease in/out between keyframes) or linear
    joints: [right_shoulder_roll, right_elbow_roll]   # output joints the motion moves; others hold home
    keyframes:
      - {t: 0.0, right_shoulder_roll: -15, right_elbow_roll: 30}
      - {t: 1.0, right_shoulder_roll: -150, right_elbow_roll: 30}

Every keyframe gives every listed joint; times start at 0 and increase; every angle lies within the joint's
range in the spec. Joint names are the output joints of `RobotDescription.joint_names` (e.g. ``left_knee``,
``waist_yaw``), so motions do not depend on gear ratios.

A keyframe may also say where the torso is, ``base: {roll: deg, pitch: deg, z: m}`` (each optional, roll and
pitch 0 by default): tilted by the IMU's roll and pitch (pitch > 0 leans forward: lying on the back is pitch -90,
on the front +90), its frame ``z`` m above the floor or, without ``z``, resting on the floor. The first keyframe's
base is where the motion starts (a get-up motion starts lying: ``roll_from_back.yaml``); the others say how the
editor draws the keyframe. A keyframe without one stands upright on the floor, as every motion did before.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError, quoted
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.mirror import mirror_partners
from toddlerbot.yaml_input import read_yaml

MOTIONS_DIR = resources.files("toddlerbot.policies") / "motions"
MAX_MOTION_BYTES = 1_000_000
"""Largest motion file read, bytes (the packaged ones are under 2 kB)."""
INTERPOLATIONS = ("smooth", "linear")
BASE_FIELDS = ("roll", "pitch", "z")
MAX_BASE_Z_M = 1.0
"""Highest torso frame a keyframe's base may give, m (the robot stands 0.56 m tall)."""


class MotionError(ToddlerbotError):
    """A motion file is malformed or asks for something the robot cannot do."""


@dataclass(frozen=True)
class BasePose:
    """Where the torso is at a keyframe (the format's ``base``)."""

    roll: float = 0.0
    """rad; > 0 tips the torso onto its right side."""
    pitch: float = 0.0
    """rad; > 0 leans it forward (lying on the back: -pi/2, on the front: +pi/2)."""
    z: float | None = None
    """Height of the torso frame above the floor, m; None: the pose rests on the floor."""


@dataclass(frozen=True)
class Motion:
    name: str
    joints: tuple[str, ...]
    times: np.ndarray
    """(k,) keyframe times, s."""
    poses: np.ndarray
    """(k, len(joints)) keyframe angles, rad."""
    interpolation: str
    bases: tuple[BasePose | None, ...] = ()
    """Each keyframe's base pose, None where it gives none (empty: none gives one)."""

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def start_base(self) -> BasePose | None:
        """Where the motion starts: the first keyframe's base pose, None for standing upright."""
        return self.bases[0] if self.bases else None

    def at(self, t: float) -> np.ndarray:
        """Joint angles (rad) of the listed joints at time t (clamped to the motion's span)."""
        t = min(max(t, 0.0), self.duration)
        i = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2))
        span = self.times[i + 1] - self.times[i]
        s = (t - self.times[i]) / span
        if self.interpolation == "smooth":
            s = s * s * (3.0 - 2.0 * s)
        return self.poses[i] + s * (self.poses[i + 1] - self.poses[i])


def full_pose(motion: Motion, description: RobotDescription, t: float = 0.0) -> np.ndarray:
    """Every output joint at time ``t`` of ``motion`` (rad, `joint_names` order): the home pose where it lists none."""
    pose = np.array(description.home_joint_pos)
    pose[[description.joint_names.index(j) for j in motion.joints]] = motion.at(t)
    return pose


def mirrored(motion: Motion, description: RobotDescription) -> Motion:
    """The motion reflected left-right (`robot.mirror`: each joint's partner and sign; a base pose's roll changes
    sign): e.g. a roll from the right side played from the left side."""
    names = description.joint_names
    partner, sign = mirror_partners(description, names)
    listed = {names[partner[names.index(j)]] for j in motion.joints} | set(motion.joints)
    joints = tuple(j for j in names if j in listed)
    index = [names.index(j) for j in joints]
    poses = []
    for t in motion.times:
        pose = full_pose(motion, description, float(t))
        reflected = np.empty_like(pose)
        reflected[partner] = sign * pose
        poses.append(reflected[index])
    bases = tuple(None if b is None else BasePose(-b.roll, b.pitch, b.z) for b in motion.bases)
    return Motion(f"{motion.name} (mirrored)", joints, motion.times.copy(), np.array(poses), motion.interpolation,
                  bases)


def builtin_motions() -> list[str]:
    return sorted(p.name.removesuffix(".yaml") for p in MOTIONS_DIR.iterdir() if p.name.endswith(".yaml"))


def motion_path(name_or_path: str) -> Path:
    """A built-in motion name (`builtin_motions`: squat, wave, look_around, the get-up motions) or a path to a motion
    file."""
    if name_or_path in builtin_motions():
        return Path(str(MOTIONS_DIR / f"{name_or_path}.yaml"))
    path = Path(name_or_path)
    if not path.is_file():
        raise MotionError(f"unknown motion {name_or_path!r}: not a built-in ({', '.join(builtin_motions())}) "
                          "nor an existing file")
    return path


def load_motion(name_or_path: str, description: RobotDescription) -> Motion:
    path = motion_path(name_or_path)
    return parse_motion(read_yaml(path, "motion file", MotionError, MAX_MOTION_BYTES), description, str(path))


def parse_motion(raw: object, description: RobotDescription, source: str) -> Motion:
    if not isinstance(raw, dict):
        raise MotionError(f"{source}: expected a mapping with name, joints and keyframes")
    for key in ("joints", "keyframes"):
        if key not in raw:
            raise MotionError(f"{source}: missing '{key}'")
    valid = description.joint_names
    joints = raw["joints"]
    if not isinstance(joints, list) or not joints:
        raise MotionError(f"{source}: 'joints' must be a non-empty list of joint names")
    for j in joints:
        if j not in valid:
            raise MotionError(f"{source}: unknown joint {j!r} in 'joints'; expected output joints like "
                              f"{', '.join(valid[:4])}, ...")
    interpolation = raw.get("interpolation", "smooth")
    if interpolation not in INTERPOLATIONS:
        raise MotionError(f"{source}: interpolation {interpolation!r} is not one of {', '.join(INTERPOLATIONS)}")
    frames = raw["keyframes"]
    if not isinstance(frames, list) or len(frames) < 2:
        raise MotionError(f"{source}: 'keyframes' must list at least two keyframes")
    times, poses, bases = [], [], []
    for i, frame in enumerate(frames):
        where = f"{source}: keyframe {i}"
        if not isinstance(frame, dict) or "t" not in frame:
            raise MotionError(f"{where}: expected a mapping with 't' and one angle per joint")
        missing = [j for j in joints if j not in frame]
        if missing:
            raise MotionError(f"{where}: missing joint(s) {', '.join(missing)} (every keyframe lists every joint)")
        extra = [k for k in frame if k not in ("t", "base") and k not in joints]
        if extra:
            raise MotionError(f"{where}: joint(s) {', '.join(map(str, extra))} not listed in 'joints'")
        pose = []
        for j in joints:
            value = frame[j]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
                raise MotionError(f"{where}: {j} must be a number of degrees, got {quoted(value)}")
            lo, hi = description.joint_range[valid.index(j)]
            rad = np.deg2rad(value)
            if not lo - 1e-9 <= rad <= hi + 1e-9:
                raise MotionError(f"{where}: {j} = {value} deg is out of range "
                                  f"[{np.rad2deg(lo):.1f}, {np.rad2deg(hi):.1f}] deg")
            pose.append(rad)
        t = frame["t"]
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not np.isfinite(t):
            raise MotionError(f"{where}: t must be a finite number of seconds, got {quoted(t)}")
        times.append(float(t))
        poses.append(pose)
        bases.append(None if "base" not in frame else parse_base(frame["base"], where))
    if times[0] != 0.0 or any(b <= a for a, b in itertools.pairwise(times)):
        raise MotionError(f"{source}: keyframe times must start at 0 and increase, got {times}")
    return Motion(name=str(raw.get("name", Path(source).stem)), joints=tuple(joints), times=np.array(times),
                  poses=np.array(poses), interpolation=interpolation,
                  bases=tuple(bases) if any(b is not None for b in bases) else ())


def parse_base(raw: object, where: str) -> BasePose:
    """A keyframe's ``base`` mapping (degrees, m), or one line naming ``where`` and the field."""
    if not isinstance(raw, dict):
        raise MotionError(f"{where}: base must be a mapping like {{roll: 0, pitch: -90}} (deg; z in m), "
                          f"got {quoted(raw)}")
    unknown = [str(k) for k in raw if k not in BASE_FIELDS]
    if unknown:
        raise MotionError(f"{where}: base.{unknown[0]} is not a base field; expected {', '.join(BASE_FIELDS)}")
    values = {}
    for field, unit, lo, hi in (("roll", "deg", -180.0, 180.0), ("pitch", "deg", -180.0, 180.0),
                                ("z", "m", 0.0, MAX_BASE_Z_M)):
        if field not in raw:
            continue
        value = raw[field]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
            raise MotionError(f"{where}: base.{field} must be a number of {unit} in [{lo:g}, {hi:g}], "
                              f"got {quoted(value)}")
        values[field] = float(value) if field == "z" else float(np.deg2rad(value))
    return BasePose(**values)
