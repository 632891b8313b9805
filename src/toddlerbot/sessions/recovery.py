"""What a run does when the robot falls (`sim run`/`hw run` ``--on-fall``): ``stop`` ends it (on the real robot:
torque off, exit 1), ``get-up`` hands the robot to the registered `get-up` policy and goes on once it stands."""

from __future__ import annotations

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies import make_policy
from toddlerbot.policies.base import Policy
from toddlerbot.robot.interface import Robot

ON_FALL = ("stop", "get-up")


def recovery_policy(on_fall: str, robot: Robot) -> Policy | None:
    """The policy a fall hands `robot` to, or None for ``stop``."""
    if on_fall not in ON_FALL:
        raise ToddlerbotError(f"--on-fall {on_fall!r}: expected one of {', '.join(ON_FALL)}")
    return None if on_fall == "stop" else make_policy("get-up", robot)
