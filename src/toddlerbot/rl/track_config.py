"""Configuration of the motion-tracking environment (`toddlerbot.rl.track_env`, ``rl train --env track``): an
`EnvConfig` with the motion, its reference's final hold, what the actor sees of the reference and the deviations
that end an episode; and its PPO recipes."""

from __future__ import annotations

from dataclasses import dataclass, replace

from toddlerbot.policies.track import TRACK_ENVIRONMENT
from toddlerbot.rl import config
from toddlerbot.rl.config import EnvConfig, ObsConfig

TRACK = TRACK_ENVIRONMENT
"""The environment's registered name."""


@dataclass(frozen=True)
class TrackConfig(EnvConfig):
    """`EnvConfig` of ``track``. Of the walking fields it uses the robot, physics, observation scales and noise,
    reward weights and randomisation (not the command, the gait or the fall thresholds: the deviations below end
    an episode). Contacts default to ``all``: a motion may touch the floor with any part of the robot."""

    environment: str = TRACK
    contacts: str = "all"
    motion: str = ""
    """A built-in motion's name (`toddlerbot.policies.motions.builtin_motions`) or a motion file's absolute path
    (`rl train --motion`; required)."""
    hold_s: float = 2.0
    """s the reference holds the motion's final pose after it."""
    lookahead: tuple[int, ...] = (1, 5, 10)
    """Control steps ahead at which the actor sees the reference's motor targets."""
    max_orientation_error: float = 0.8
    """rad; the episode ends when the torso turns further than this from the reference's orientation..."""
    max_height_error: float = 0.1
    """...its height differs by more than this, m..."""
    max_position_error: float = 0.3
    """...or it is further than this from the reference's torso horizontally, m."""

    def __post_init__(self) -> None:
        super().__post_init__()
        band = self.randomization
        if band.upper_body_pose or band.hand_force:
            raise ValueError(f"upper-body pose {band.upper_body_pose}, hand force {band.hand_force}: the {TRACK} "
                             "environment follows the motion's arms (expected 0)")
        if self.hold_s < 0 or not self.lookahead or min(self.lookahead) < 0:
            raise ValueError(f"hold_s {self.hold_s}, lookahead {self.lookahead}: expected a hold >= 0 s and at least "
                             "one look-ahead >= 0 steps")


SMOKE_TRACK = replace(TrackConfig(), obs=replace(ObsConfig(), history=3), hold_s=0.5)
"""The smoke run's configuration, without the motion (a 3-frame history, half a second's hold)."""

CPU = replace(config.CPU, episode_length=500, init_action_scale=0.01, learning_rate=1e-5)
"""The CPU recipe's PPO (`config.CPU`: 256 environments, exploration noise 0.1) without a warm start, and 10 s
episodes (the squat and its hold are 9 s). With no warm start the fresh actor's output layer is scaled to 1 % (its
first mean actions near zero: it starts by replaying the reference) and the learning rate starts at the adaptive
rule's floor (it grows while the KL stays small): at the walk's 3e-4 the first minibatches moved some mean actions
to +-1.7 (0.4 rad) with a KL of 11, and the rate then sat at the floor with the policy far off its reference."""
FULL = replace(config.FULL, episode_length=500, init_std=0.1, init_action_scale=0.01, learning_rate=1e-5)
"""The one-GPU configuration with 10 s episodes and the CPU recipe's exploration noise (the residual around the
reference is a correction, and wider noise ends most episodes by itself, docs/rl.md "Motion tracking"), started
as the CPU recipe is."""
