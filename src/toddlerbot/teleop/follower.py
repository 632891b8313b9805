"""The follower side of leader-follower teleoperation: leader angles -> safe follower arm targets.

Per control step the follower's arm and gripper targets move towards the leader's angles by at most
``max_step`` rad (so a jump of the leader, or a reconnect, never snaps the arm); when the leader is lost (no new
message for ``stale_after`` s, or a bus error on its side) the targets hold where they were and `status` says so.
The `Robot` interface's `CommandGuard` still applies on top (ranges, finiteness).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STALE_AFTER = 0.2
"""s without a new leader reading before the follower holds."""


@dataclass(frozen=True)
class FollowerConfig:
    max_step: float = 0.05
    """Largest change of an arm or gripper target per control step, rad (2.5 rad/s at 50 Hz)."""
    stale_after: float = STALE_AFTER


class ArmFollower:
    """Maps leader readings (names -> rad) onto the follower's motor targets."""

    def __init__(self, motor_names: tuple[str, ...], follow: tuple[str, ...], config: FollowerConfig | None = None):
        self.config = config or FollowerConfig()
        missing = [n for n in follow if n not in motor_names]
        if missing:
            raise ValueError(f"follower has no motor(s) {', '.join(missing)}")
        self.follow = tuple(follow)
        self.indices = np.array([motor_names.index(n) for n in follow])
        self.status = "waiting for leader"
        self.holding = True
        self.events: list[str] = []
        """Status changes, in order (for the operator's console and the tests)."""

    def targets(self, current: np.ndarray, leader_names: tuple[str, ...] | None, leader_values: np.ndarray | None,
                age: float) -> np.ndarray:
        """New full motor-target vector from the `current` targets and the leader's latest reading, `age` s old
        (None/inf when there is none)."""
        out = np.array(current, dtype=float)
        if leader_values is None or leader_names is None or not age <= self.config.stale_after:
            stale = f"leader stale ({age:.2f} s): holding last safe targets"
            self._set_status("waiting for leader" if leader_values is None else stale, holding=True)
            return out
        lookup = dict(zip(leader_names, leader_values))
        missing = [n for n in self.follow if n not in lookup]
        if missing:
            self._set_status(f"leader message lacks {', '.join(missing)}: holding last safe targets", holding=True)
            return out
        goal = np.array([lookup[n] for n in self.follow])
        step = np.clip(goal - out[self.indices], -self.config.max_step, self.config.max_step)
        out[self.indices] += step
        self._set_status("following leader", holding=False)
        return out

    def lost(self, reason: str) -> None:
        """The leader side reported a failure (e.g. a bus error): hold."""
        self._set_status(f"leader lost ({reason}): holding last safe targets", holding=True)

    def _set_status(self, status: str, holding: bool) -> None:
        if status.split(" (")[0] != self.status.split(" (")[0]:
            self.events.append(status)
        self.status, self.holding = status, holding
