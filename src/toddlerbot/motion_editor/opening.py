"""What the editor opens: a new motion, a built-in one or a motion file, and where Save writes it."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.motion_editor.keyframes import Keyframes
from toddlerbot.policies.motions import MAX_MOTION_BYTES, MotionError, builtin_motions, motion_path, parse_motion
from toddlerbot.robot.description import RobotDescription
from toddlerbot.yaml_input import read_yaml


def open_keyframes(motion: str | None, description: RobotDescription,
                   out: Path | None) -> tuple[Keyframes, Path | None]:
    """The keyframes of `motion` (None: a new motion named after `out`) and the file Save writes: `out`, else the
    opened file; a built-in motion is never overwritten (None: the page asks for a name)."""
    if motion is None:
        return Keyframes.new(description, name=out.stem if out else "motion"), out
    path = motion_path(motion)
    raw = read_yaml(path, "motion file", MotionError, MAX_MOTION_BYTES)
    parsed = parse_motion(raw, description, str(path))
    keyframes = Keyframes.from_motion(parsed, description, text=str(raw.get("description", "")))
    if out is None and motion not in builtin_motions():
        return keyframes, path
    return keyframes, out
