"""Training wrappers around `WalkEnv`: batching, episode bookkeeping and a full auto-reset.

Brax's own ``AutoResetWrapper`` restores only the physics state and observation of the first reset, keeping the
finished episode's ``info``; our ``info`` carries the command, the domain-randomisation draw, the observation
history and the push schedule, so `FullAutoReset` replaces all of it with a fresh ``reset`` (new draw) instead.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State, Wrapper
from brax.envs.wrappers.training import EpisodeWrapper, VmapWrapper

_EPISODE_KEYS = ("steps", "truncation", "episode_done", "episode_metrics")


class FullAutoReset(Wrapper):
    """Resets finished envs (batched) to a new episode drawn with their own rng."""

    def __init__(self, env: Env, base: Env) -> None:
        super().__init__(env)
        self._base_reset = jax.vmap(base.reset)

    def step(self, state: State, action: jax.Array) -> State:
        steps = jnp.where(state.done > 0, 0.0, state.info["steps"])
        state = state.replace(done=jnp.zeros_like(state.done), info={**state.info, "steps": steps})
        state = self.env.step(state, action)
        fresh = self._base_reset(state.info["rng"])

        def pick(new: jax.Array, old: jax.Array) -> jax.Array:
            done = jnp.reshape(state.done > 0, state.done.shape + (1,) * (old.ndim - state.done.ndim))
            return jnp.where(done, new, old)

        info = {k: (v if k in _EPISODE_KEYS else jax.tree.map(pick, fresh.info[k], v)) for k, v in state.info.items()}
        return state.replace(pipeline_state=jax.tree.map(pick, fresh.pipeline_state, state.pipeline_state),
                             obs=jax.tree.map(pick, fresh.obs, state.obs), info=info)


def wrap_for_training(env: Env, episode_length: int) -> Env:
    """Batched env (reset takes a batch of keys) with episode truncation and full auto-reset."""
    return FullAutoReset(EpisodeWrapper(VmapWrapper(env), episode_length, action_repeat=1), env)
