"""The tiny target task of `ppo_support` as a registered RL environment, so that ``rl train`` trains it as it trains
the robot (options, run directory, checkpoints, ``--resume``, several processes) in seconds instead of minutes.

Run as a script it is ``toddlerbot`` with that environment registered:
``python rl_distributed_support.py PARAMS.npz rl train --env target-test ...`` runs the command and writes the
training state ``rl.train.train`` returned in this process (its network parameters, normaliser and step count) to
PARAMS.npz, which `tests/test_rl_distributed.py` compares across processes.
"""

import sys
from dataclasses import replace

from ppo_support import CFG, TargetEnv
from toddlerbot.rl.config import EnvConfig, ImitationConfig, Recipe
from toddlerbot.rl.environment import RLEnvironment
from toddlerbot.rl.environments import ENVIRONMENTS
from toddlerbot.rl.rewards import RewardTerms

NAME = "target-test"
UPDATES_PER_EPOCH = 5
TINY = replace(CFG, num_timesteps=4 * UPDATES_PER_EPOCH * CFG.env_steps_per_update, num_evals=4)
"""`ppo_support.CFG` in 4 epochs of 5 PPO updates (16 envs x 8 steps x 4 minibatches each)."""


class TargetTask(TargetEnv, RLEnvironment):
    """`ppo_support.TargetEnv` with a registered environment's bundle: no reward table of terms, the same tiny
    recipe on every backend, nothing to record for an export."""

    name = NAME
    reward_terms = RewardTerms()
    recipes = dict.fromkeys(("cpu", "mjx", "smoke"), Recipe(TINY, ImitationConfig(iterations=0)))

    def __init__(self, cfg: EnvConfig) -> None:
        self.cfg = cfg

    @classmethod
    def default_config(cls, smoke: bool = False) -> EnvConfig:
        return EnvConfig(environment=NAME)

    def record_action_space(self, run_dir) -> None:
        pass


def register() -> None:
    if NAME not in ENVIRONMENTS:
        ENVIRONMENTS.register(NAME, TargetTask)


def print_learning_curves(seeds: int) -> None:
    """Train `ppo_support.CFG` from each of ``seeds`` seeds on this process's JAX devices, and print one JSON line:
    the device count, each seed's step reward per update, and the largest difference between the devices' copies of
    the network parameters after one more epoch (0 where gradients are averaged over the devices)."""
    import json

    import jax
    import jax.numpy as jnp

    from toddlerbot.rl import train

    ppo = train.PPO(TargetEnv(), CFG)
    curves = []
    for seed in range(seeds):
        k_init, k_env, key = jax.random.split(jax.random.PRNGKey(seed), 3)
        ts, env_state = ppo.initial_state(k_init), ppo.reset(k_env)
        curve = []
        for _ in range(ppo.epochs):
            key, k_epoch = jax.random.split(key)
            ts, env_state, metrics = ppo.epoch(ts, env_state, k_epoch)
            curve.append(metrics["step_reward"])
        curves.append(curve)
    n = jax.local_device_count()  # the epoch's own placement (`PPO.epoch`), every device's copy kept
    replicas, _, _ = ppo._p_epoch(train._per_device(jax.tree.map(lambda x: jnp.broadcast_to(x, (n, *x.shape)), ts)),
                                  env_state, train._per_device(jax.random.split(key, n)))
    spread = max(float(jnp.max(jnp.abs(x - x[:1]))) for x in jax.tree.leaves(replicas.params))
    print(json.dumps({"devices": n, "step_reward": curves, "replica_spread": spread}))


def _main() -> None:
    import jax
    import numpy as np

    from toddlerbot.cli.main import main
    from toddlerbot.rl import train

    register()
    out, train_run = sys.argv.pop(1), train.train

    def train_and_keep(*args, **kwargs):
        state, history = train_run(*args, **kwargs)
        leaves = jax.tree.leaves(jax.device_get((state.params, state.normalizer_params, state.env_steps)))
        np.savez(out, *leaves)
        return state, history

    train.train = train_and_keep  # the CLI looks it up when it trains
    main()


if __name__ == "__main__":
    _main()
