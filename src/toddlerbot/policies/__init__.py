"""Policies (observation + command -> motor targets) and the registry the CLI uses."""

from __future__ import annotations

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Robot

POLICIES = ("stand", "replay", "walk-zmp")

__all__ = ["POLICIES", "Action", "Policy", "make_policy"]


def make_policy(name: str, robot: Robot, motion: str | None = None) -> Policy:
    """Build a policy by name; ``motion`` (a built-in name or a file) is required by ``replay``."""
    if name == "stand":
        from toddlerbot.policies.stand import StandPolicy

        return StandPolicy(robot)
    if name == "replay":
        from toddlerbot.policies.motions import load_motion
        from toddlerbot.policies.replay import ReplayPolicy

        if motion is None:
            raise ToddlerbotError("policy 'replay' needs --motion (squat, wave, look_around or a motion file)")
        return ReplayPolicy(robot, load_motion(motion, robot.spec))
    if name == "walk-zmp":
        from toddlerbot.policies.walk_zmp import WalkZMPPolicy

        return WalkZMPPolicy(robot)
    raise ToddlerbotError(f"unknown policy {name!r}; expected one of {', '.join(POLICIES)}")
