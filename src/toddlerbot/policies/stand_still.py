"""Standing still at a zero command (issue 42): when walk-rl stands and when it walks.

A walking policy trained to step in place at a zero command wanders while it does (the shipped ``walk_rl.npz``:
0.22 m in 60 s). `StandStill` holds the home pose instead: a run starts standing, a command that is not zero hands
the robot to the gait (which then starts as a training episode does, from phase 0), and once the command has been
zero for `StandStill.after` s the robot stands again at the next moment both feet of the gait reference are down,
its targets moving from the gait's last ones to the home pose over `StandStill.blend` s. Standing takes 0.3 m/s
kicks as well as stepping does; docs/rl.md "Standing still" has the figures.
"""

from __future__ import annotations

import numpy as np

STAND_AFTER_S = 0.5
"""s of zero command before the robot stands (0.3-1.0 s measured alike; 0.5 s lets the gait finish a step)."""
STAND_BLEND_S = 0.3
"""s over which the targets move from the gait's last ones to the home pose."""


class StandStill:
    """Decides, tick by tick, whether a walker stands, and the motor targets while it does."""

    def __init__(self, home_motor_pos: np.ndarray, after: float = STAND_AFTER_S, blend: float = STAND_BLEND_S) -> None:
        self.home = np.asarray(home_motor_pos, dtype=float)
        self.after, self.blend = after, blend
        self.since: float | None = None
        """When the robot last started standing, s (None while it walks)."""
        self.start = self.home
        """The motor targets the stance blends from."""
        self.zero_since: float | None = None
        """Since when the command has been zero, s (None while it is not)."""

    @property
    def standing(self) -> bool:
        return self.since is not None

    def reset(self, time: float, motor_pos: np.ndarray) -> None:
        """Start standing, from the measured motor angles."""
        self.since, self.start, self.zero_since = time, np.asarray(motor_pos, dtype=float), time

    def update(self, time: float, command: np.ndarray, both_feet_down: bool, walk_targets: np.ndarray) -> bool:
        """Take this tick's command (the walker's, after clamping) and whether the gait reference has both feet
        down now, with the gait's last motor targets; returns whether the robot stands this tick."""
        if np.any(command):
            self.since = self.zero_since = None
            return False
        if self.zero_since is None:
            self.zero_since = time
        if self.since is None and both_feet_down and time - self.zero_since >= self.after - 1e-9:
            self.since, self.start = time, np.asarray(walk_targets, dtype=float)
        return self.standing

    def targets(self, time: float) -> np.ndarray:
        """Motor targets while standing: from `start` to the home pose, linearly over `blend` s."""
        a = min(1.0, (time - self.since) / self.blend) if self.blend > 0 else 1.0
        return (1.0 - a) * self.start + a * self.home
