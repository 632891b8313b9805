"""A second RL environment registered by a script, as a user would add one: the walking robot asked only to stand,
rewarded by its own three-term table. `tests/test_rl_environments.py` trains it through the registry."""

from dataclasses import replace

from toddlerbot.rl import rewards
from toddlerbot.rl.config import CommandConfig, EnvConfig, smoke_env_config
from toddlerbot.rl.environments import ENVIRONMENTS
from toddlerbot.rl.walk_env import WalkEnv

NAME = "stand-test"
STAND_REWARDS = rewards.RewardTerms((rewards.survival, 10.0), (rewards.stand_still, 1.0),
                                    (rewards.leg_action_rate, 0.05))
"""At most 10 x the control period per step: standing earns survival only."""


class StandEnv(WalkEnv):
    name = NAME
    reward_terms = STAND_REWARDS

    @classmethod
    def default_config(cls, smoke: bool = False) -> EnvConfig:
        base = smoke_env_config() if smoke else EnvConfig()
        return replace(base, environment=NAME, command=replace(CommandConfig(), grid=(3, 2, 2), stand_prob=1.0))


def register() -> None:
    """Register `StandEnv` once in this process."""
    if NAME not in ENVIRONMENTS:
        ENVIRONMENTS.register(NAME, StandEnv)
