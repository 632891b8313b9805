"""Policies (observation + command -> motor targets) and the registry the CLI uses."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import Robot

POLICIES = ("stand", "replay", "walk-zmp", "walk-rl")
MAX_PREVIEW_TICKS = 2400
"""Longest ZMP preview walk-zmp plans with, ticks (its 1.2 s preview at 0.5 ms): a shorter control period would
make planning the gait itself the run (at 1 ns: 1.2e9 ticks, minutes of CPU and gigabytes)."""

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

        return WalkZMPPolicy(robot, _walk_config(robot.control_dt))
    if name == "walk-rl":
        from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS, WalkRLPolicy

        return WalkRLPolicy(robot, weights or DEFAULT_WEIGHTS)
    raise ToddlerbotError(f"unknown policy {name!r}; expected one of {', '.join(POLICIES)}")


def _walk_config(dt: float):
    """The gait configuration at control period `dt` (s), or one line saying why walk-zmp cannot plan at it."""
    from toddlerbot.locomotion.config import WalkConfig

    cannot = f"walk-zmp cannot plan at a control period of {dt:g} s"
    try:
        config = WalkConfig(dt=dt)
    except ValueError as exc:
        raise ToddlerbotError(f"{cannot}: {exc}") from None
    if config.preview_ticks > MAX_PREVIEW_TICKS:
        raise ToddlerbotError(f"{cannot}: its {config.preview_time:g} s preview would be {config.preview_ticks} "
                              f"ticks (at most {MAX_PREVIEW_TICKS}); use a period of at least "
                              f"{config.preview_time / MAX_PREVIEW_TICKS:g} s")
    return config
