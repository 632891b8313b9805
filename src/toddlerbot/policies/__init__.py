"""Policies (observation + command -> motor targets) and the registry the CLI uses."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Robot

POLICIES = ("stand", "replay", "walk-zmp", "walk-rl")

__all__ = ["POLICIES", "Action", "Policy", "make_policy"]


def make_policy(name: str, robot: Robot, motion: str | None = None, weights: str | Path | None = None) -> Policy:
    """Build a policy by name; ``motion`` (a built-in name or a file) is required by ``replay``; ``weights`` is an
    exported RL policy for ``walk-rl`` (default: the shipped one)."""
    if name == "stand":
        from toddlerbot.policies.stand import StandPolicy

        return StandPolicy(robot)
    if name == "replay":
        from toddlerbot.policies.motions import load_motion
        from toddlerbot.policies.replay import ReplayPolicy

        if motion is None:
            raise ToddlerbotError("policy 'replay' needs --motion (squat, wave, look_around or a motion file)")
        return ReplayPolicy(robot, load_motion(motion, robot.description))
    if name == "walk-zmp":
        from toddlerbot.policies.walk_zmp import WalkZMPPolicy

        return WalkZMPPolicy(robot)
    if name == "walk-rl":
        from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS, WalkRLPolicy

        return WalkRLPolicy(robot, weights or DEFAULT_WEIGHTS)
    raise ToddlerbotError(f"unknown policy {name!r}; expected one of {', '.join(POLICIES)}")
