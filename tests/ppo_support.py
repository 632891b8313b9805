"""A tiny pure-JAX task for the PPO loop's tests (`test_rl_ppo`, `test_rl_mirror_loss`): each step asks for the
action that equals a random target shown in the observation (reward 1 - mean squared error), which a Gaussian
policy learns within a few updates, so the loop compiles in about a minute instead of several on the robot."""

import functools

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State
from brax.training import acting

from toddlerbot.rl.config import PPOConfig

N_ACT = 4


class TargetEnv(Env):
    """Observation: a random target in [-0.8, 0.8]^4 (offset and scaled so normalisation matters); reward:
    1 - mean squared distance of the clipped action to it."""

    def _obs(self, target):
        return {"state": 3.0 + 5.0 * target, "privileged_state": target}

    def reset(self, rng):
        rng, k = jax.random.split(rng)
        target = jax.random.uniform(k, (N_ACT,), minval=-0.8, maxval=0.8)
        return State(None, self._obs(target), jnp.zeros(()), jnp.zeros(()), {}, {"rng": rng, "target": target})

    def step(self, state, action):
        action = jnp.clip(action, -1.0, 1.0)
        reward = 1.0 - jnp.mean((action - state.info["target"]) ** 2)
        rng, k = jax.random.split(state.info["rng"])
        target = jax.random.uniform(k, (N_ACT,), minval=-0.8, maxval=0.8)
        return state.replace(obs=self._obs(target), reward=reward, info={**state.info, "rng": rng, "target": target})

    @property
    def observation_size(self):
        return {"state": (N_ACT,), "privileged_state": (N_ACT,)}

    @property
    def action_size(self):
        return N_ACT

    @property
    def backend(self):
        return "none"


UPDATES = 25
CFG = PPOConfig(num_timesteps=UPDATES * 16 * 4 * 8, num_envs=16, episode_length=50, unroll_length=8,
                batch_size=16, num_minibatches=4, num_updates_per_batch=4, policy_hidden=(32, 32),
                value_hidden=(32, 32), num_evals=UPDATES, num_eval_envs=0, discounting=0.9, seed=3)


def unroll_batch(ppo, ts):
    """One [B, T] batch of `CFG.unroll_length` steps of fresh envs under the policy of training state ``ts``."""
    env_state = jax.jit(ppo.train_env.reset)(jax.random.split(jax.random.PRNGKey(2), CFG.num_envs))
    policy = ppo.make_policy((ts.normalizer_params, ts.params.policy, ts.params.value))
    _, data = jax.jit(functools.partial(acting.generate_unroll, ppo.train_env, policy=policy,
                                        unroll_length=CFG.unroll_length, extra_fields=("truncation",)))(
        env_state, key=jax.random.PRNGKey(3))
    return jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), data)


def small_run(folder):
    """A training run directory (config + one checkpoint of a small network, some action means beyond +-1) as
    `rl train` leaves it, made in a second instead of a training's minutes."""
    from toddlerbot.policies.rl_inference import ObsConfig
    from toddlerbot.rl import train
    from toddlerbot.rl.config import EnvConfig
    from toddlerbot.rl.export import _template
    from toddlerbot.robot.description import RobotDescription

    run = folder / "run"
    env_cfg = EnvConfig(obs=ObsConfig(history=2, gait_period=0.72), residual=False)
    ppo_cfg = PPOConfig(num_envs=8, batch_size=8, policy_hidden=(32, 16), value_hidden=(16,))
    run.mkdir()
    train.save_config(run, env_cfg, ppo_cfg)
    description = RobotDescription.load()
    legs = len(description.group_names("leg"))
    actor = env_cfg.obs.history * env_cfg.obs.frame_size(description.n_motors, legs)
    state, _ = _template(ppo_cfg, {"state": (actor,), "privileged_state": (7,)}, legs)
    policy = state.params.policy
    head = policy["params"]["Dense_0"]
    policy["params"]["Dense_0"] = {**head, "kernel": head["kernel"] * 6.0}
    state = state.replace(params=state.params.replace(policy=policy), env_steps=jnp.asarray(4096))
    train.save_checkpoint(run, state, jax.random.PRNGKey(0), [{"env_steps": 4096, "walltime": 1.0}])
    return run
