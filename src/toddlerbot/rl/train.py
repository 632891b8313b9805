"""PPO training of the walking policy with Brax's PPO components and fully resumable checkpoints.

Brax's ``ppo.train`` saves only network parameters, so this module runs the same algorithm (Brax's networks,
loss, GAE, running observation statistics and rollout code, Table 5 hyperparameters) in its own loop and
checkpoints the whole `TrainingState`: network parameters, Adam optimiser state, observation normaliser and
the step counter, plus the PRNG key and the metric history. ``resume`` continues a run bit-for-bit from its
last checkpoint except for the environments, which start fresh episodes.

Devices: the epoch is ``jax.pmap``-ed over all local JAX devices (``num_envs`` is split between them and
gradients are averaged with ``pmean``), so several GPUs on one host are used without changes. Select devices
with ``CUDA_VISIBLE_DEVICES``.

Run directory layout: ``config.json``, ``checkpoints/step_<n>.msgpack``, ``metrics.jsonl``,
``training_curve.png``.
"""

from __future__ import annotations

import functools
import json
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import flax
import jax
import jax.numpy as jnp
import numpy as np
import optax
from brax.training import acting, gradients, types
from brax.training.acme import running_statistics, specs
from brax.training.agents.ppo import losses as ppo_losses
from brax.training.agents.ppo import networks as ppo_networks
from flax import serialization

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_bytes, atomic_write_text
from toddlerbot.rl.config import (
    CommandConfig,
    EnvConfig,
    ObsConfig,
    PPOConfig,
    RandomizationConfig,
    RewardConfig,
)
from toddlerbot.rl.env import WalkEnv
from toddlerbot.rl.wrappers import wrap_for_training

AXIS = "devices"
Progress = Callable[[int, int, dict[str, float]], None]
"""progress(env_steps_done, env_steps_total, metrics)."""


@flax.struct.dataclass
class TrainingState:
    optimizer_state: optax.OptState
    params: ppo_losses.PPONetworkParams
    normalizer_params: running_statistics.RunningStatisticsState
    env_steps: jax.Array


def make_networks(obs_size: dict, action_size: int, cfg: PPOConfig) -> ppo_networks.PPONetworks:
    return ppo_networks.make_ppo_networks(
        obs_size, action_size,
        preprocess_observations_fn=running_statistics.normalize if cfg.normalize_observations
        else types.identity_observation_preprocessor,
        policy_hidden_layer_sizes=cfg.policy_hidden, value_hidden_layer_sizes=cfg.value_hidden,
        policy_obs_key="state", value_obs_key="privileged_state",
    )


def _initial_state(networks: ppo_networks.PPONetworks, optimizer: optax.GradientTransformation, obs_size: dict,
                   key: jax.Array) -> TrainingState:
    k_policy, k_value = jax.random.split(key)
    params = ppo_losses.PPONetworkParams(policy=networks.policy_network.init(k_policy),
                                         value=networks.value_network.init(k_value))
    obs_spec = {k: specs.Array(v, jnp.dtype("float32")) for k, v in obs_size.items()}
    return TrainingState(optimizer_state=optimizer.init(params), params=params,
                         normalizer_params=running_statistics.init_state(obs_spec),
                         env_steps=jnp.zeros((), jnp.int32))


# configuration files -------------------------------------------------------------------------------------------
def save_config(run_dir: Path, env_cfg: EnvConfig, ppo_cfg: PPOConfig) -> None:
    atomic_write_text(run_dir / "config.json", json.dumps({"env": asdict(env_cfg), "ppo": asdict(ppo_cfg)}, indent=1))


def load_config(run_dir: Path) -> tuple[EnvConfig, PPOConfig]:
    path = run_dir / "config.json"
    if not path.is_file():
        raise ToddlerbotError(f"{path}: no training run here (config.json missing)")
    raw = json.loads(path.read_text())
    env = dict(raw["env"])
    tuples = lambda d: {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}  # noqa: E731
    env_cfg = EnvConfig(
        **{k: v for k, v in tuples(env).items() if k not in ("obs", "command", "reward", "randomization")},
        obs=ObsConfig(**env["obs"]), command=CommandConfig(**tuples(env["command"])),
        reward=RewardConfig(**tuples(env["reward"])), randomization=RandomizationConfig(**tuples(env["randomization"])),
    )
    return env_cfg, PPOConfig(**tuples(raw["ppo"]))


# checkpoints ----------------------------------------------------------------------------------------------------
def checkpoint_paths(run_dir: Path) -> list[Path]:
    return sorted((run_dir / "checkpoints").glob("step_*.msgpack"))


def save_checkpoint(run_dir: Path, state: TrainingState, key: jax.Array, history: list[dict]) -> Path:
    """Write the full training state atomically (temporary file, then rename)."""
    folder = run_dir / "checkpoints"
    folder.mkdir(parents=True, exist_ok=True)
    payload = {"state": serialization.to_state_dict(jax.device_get(state)), "key": np.asarray(jax.device_get(key)),
               "history": json.dumps(history)}
    path = folder / f"step_{int(state.env_steps):012d}.msgpack"
    return atomic_write_bytes(path, serialization.msgpack_serialize(payload))


def load_checkpoint(path: Path, template: TrainingState) -> tuple[TrainingState, jax.Array, list[dict]]:
    try:
        payload = serialization.msgpack_restore(path.read_bytes())
        state = serialization.from_state_dict(template, payload["state"])
    except (ValueError, KeyError) as exc:
        raise ToddlerbotError(f"{path}: not a checkpoint of this configuration ({exc})") from exc
    shapes = [(np.shape(a), np.shape(b)) for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(template),
                                                         strict=True)]
    if any(a != b for a, b in shapes):
        first = next((a, b) for a, b in shapes if a != b)
        raise ToddlerbotError(f"{path}: not a checkpoint of this configuration (array of shape {first[0]} where "
                              f"the networks need {first[1]})")
    return state, jnp.asarray(payload["key"]), json.loads(payload["history"])


# training --------------------------------------------------------------------------------------------------------
def train(run_dir: Path, env_cfg: EnvConfig | None = None, ppo_cfg: PPOConfig | None = None, resume: bool = False,
          progress: Progress | None = None, env: WalkEnv | None = None, max_epochs: int | None = None,
          time_limit_s: float | None = None) -> tuple[TrainingState, list[dict]]:
    """Train (or, with ``resume``, continue training) into ``run_dir``; returns the final state and the metric
    history (one dict per epoch). ``max_epochs`` / ``time_limit_s`` stop this call early (after a checkpoint);
    ``resume`` continues from there."""
    t_start = time.perf_counter()
    run_dir = Path(run_dir)
    if resume:
        env_cfg, ppo_cfg = load_config(run_dir)
    else:
        env_cfg, ppo_cfg = env_cfg or EnvConfig(), ppo_cfg or PPOConfig()
    cfg = ppo_cfg
    env = env or WalkEnv(env_cfg)
    if not resume:
        run_dir.mkdir(parents=True, exist_ok=True)
        save_config(run_dir, env.cfg, ppo_cfg)
        atomic_write_text(run_dir / "reference.txt", env.reference_source + "\n")
    n_dev = jax.local_device_count()
    if cfg.num_envs % n_dev:
        raise ToddlerbotError(f"num_envs {cfg.num_envs} is not divisible by the {n_dev} JAX devices")
    envs_per_dev = cfg.num_envs // n_dev
    train_env = wrap_for_training(env, cfg.episode_length)
    obs_size = env.observation_size
    networks = make_networks(obs_size, env.action_size, cfg)
    make_policy = ppo_networks.make_inference_fn(networks)
    optimizer = optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm), optax.adam(cfg.learning_rate))
    loss_fn = functools.partial(
        ppo_losses.compute_ppo_loss, ppo_network=networks, entropy_cost=cfg.entropy_cost,
        discounting=cfg.discounting, reward_scaling=cfg.reward_scaling, gae_lambda=cfg.gae_lambda,
        clipping_epsilon=cfg.clipping_epsilon, normalize_advantage=True,
    )
    loss_and_grad = gradients.loss_and_pgrad(loss_fn, pmap_axis_name=AXIS, has_aux=True)
    rollouts = cfg.batch_size * cfg.num_minibatches // cfg.num_envs

    def minibatch_step(carry, data, normalizer):
        opt_state, params, key = carry
        key, k_loss = jax.random.split(key)
        (_, metrics), grads = loss_and_grad(params, normalizer, data, k_loss)
        updates, opt_state = optimizer.update(grads, opt_state, params)
        return (opt_state, optax.apply_updates(params, updates), key), metrics

    def sgd_step(carry, _, data, normalizer):
        opt_state, params, key = carry
        key, k_perm, k_grad = jax.random.split(key, 3)
        shuffled = jax.tree.map(
            lambda x: jax.random.permutation(k_perm, x).reshape((cfg.num_minibatches, -1, *x.shape[1:])), data)
        (opt_state, params, _), metrics = jax.lax.scan(
            functools.partial(minibatch_step, normalizer=normalizer), (opt_state, params, k_grad), shuffled)
        return (opt_state, params, key), metrics

    def training_step(carry, _):
        ts, env_state, key = carry
        k_sgd, k_unroll, key = jax.random.split(key, 3)
        policy = make_policy((ts.normalizer_params, ts.params.policy, ts.params.value))

        def unroll(c, _):
            state, k = c
            k, k_next = jax.random.split(k)
            state, data = acting.generate_unroll(train_env, state, policy, k, cfg.unroll_length,
                                                 extra_fields=("truncation", "episode_metrics", "episode_done"))
            return (state, k_next), data

        (env_state, _), data = jax.lax.scan(unroll, (env_state, k_unroll), None, length=rollouts)
        data = jax.tree.map(lambda x: jnp.swapaxes(x, 1, 2), data)
        data = jax.tree.map(lambda x: x.reshape((-1, *x.shape[2:])), data)
        normalizer = running_statistics.update(ts.normalizer_params, data.observation, pmap_axis_name=AXIS)
        (opt_state, params, _), metrics = jax.lax.scan(
            functools.partial(sgd_step, data=data, normalizer=normalizer),
            (ts.optimizer_state, ts.params, k_sgd), None, length=cfg.num_updates_per_batch)
        extras = data.extras["state_extras"]
        done = extras["episode_done"]
        n_done = jnp.sum(done)
        metrics = jax.tree.map(jnp.mean, metrics)
        metrics.update(
            episode_reward=jnp.sum(extras["episode_metrics"]["sum_reward"] * done) / jnp.maximum(n_done, 1),
            episode_length=jnp.sum(extras["episode_metrics"]["length"] * done) / jnp.maximum(n_done, 1),
            episodes=n_done, step_reward=jnp.mean(data.reward),
            fall_rate=jnp.sum(done * (1 - extras["truncation"])) / done.size,
        )
        ts = TrainingState(opt_state, params, normalizer, ts.env_steps + cfg.env_steps_per_update)
        return (ts, env_state, key), metrics

    updates_total = -(-cfg.num_timesteps // cfg.env_steps_per_update)
    epochs = max(1, min(cfg.num_evals, updates_total))
    updates_per_epoch = -(-updates_total // epochs)

    def epoch(ts, env_state, key):
        (ts, env_state, _), metrics = jax.lax.scan(training_step, (ts, env_state, key), None,
                                                   length=updates_per_epoch)
        return ts, env_state, jax.tree.map(lambda m: jax.lax.pmean(jnp.mean(m), AXIS), metrics)

    p_epoch = jax.pmap(epoch, axis_name=AXIS)
    p_reset = jax.pmap(train_env.reset, axis_name=AXIS)

    key = jax.random.PRNGKey(cfg.seed)
    key, k_init = jax.random.split(key)
    ts = _initial_state(networks, optimizer, obs_size, k_init)
    history: list[dict] = []
    if resume:
        paths = checkpoint_paths(run_dir)
        if not paths:
            raise ToddlerbotError(f"{run_dir}: no checkpoint to resume from")
        ts, key, history = load_checkpoint(paths[-1], ts)
    evaluator = _evaluator(env, make_policy, cfg, key) if cfg.num_eval_envs > 0 else None

    replicate = lambda x: jnp.broadcast_to(x, (n_dev, *jnp.shape(x)))  # noqa: E731
    p_ts = jax.tree.map(replicate, ts)
    key, k_env = jax.random.split(key)
    env_state = p_reset(jax.random.split(k_env, cfg.num_envs).reshape(n_dev, envs_per_dev, -1))
    total = updates_per_epoch * epochs * cfg.env_steps_per_update
    walltime = sum(h["epoch_seconds"] for h in history)
    epochs_run = 0
    while int(ts.env_steps) < total:
        if (max_epochs is not None and epochs_run >= max_epochs) or (
                time_limit_s is not None and time.perf_counter() - t_start > time_limit_s):
            break
        epochs_run += 1
        key, k_epoch = jax.random.split(key)
        t0 = time.perf_counter()
        p_ts, env_state = _strip_weak_types((p_ts, env_state))  # else every epoch's new dtypes recompile
        p_ts, env_state, metrics = p_epoch(p_ts, env_state, jax.random.split(k_epoch, n_dev))
        metrics = {k: float(v[0]) for k, v in metrics.items()}
        seconds = time.perf_counter() - t0
        walltime += seconds
        ts = jax.tree.map(lambda x: x[0], p_ts)
        steps = int(ts.env_steps)
        record = {"env_steps": steps, "epoch_seconds": seconds, "walltime": walltime,
                  "sps": updates_per_epoch * cfg.env_steps_per_update / seconds, **metrics}
        if evaluator is not None:
            eval_metrics = evaluator.run_evaluation((ts.normalizer_params, ts.params.policy, ts.params.value), {})
            record.update({k: float(v) for k, v in eval_metrics.items() if np.ndim(v) == 0})
        history.append(record)
        save_checkpoint(run_dir, ts, key, history)
        with (run_dir / "metrics.jsonl").open("a") as f:
            f.write(json.dumps(record) + "\n")
        if progress:
            progress(steps, total, record)
    return ts, history


def _strip_weak_types(tree):
    """The same arrays without JAX's weak-type flag, so that a jitted function sees one signature every call."""
    return jax.tree.map(lambda x: jnp.asarray(x).astype(jnp.asarray(x).dtype), tree)


def _evaluator(env: WalkEnv, make_policy, cfg: PPOConfig, key: jax.Array) -> acting.Evaluator:
    return acting.Evaluator(wrap_for_training(env, cfg.eval_episode_length),
                            functools.partial(make_policy, deterministic=True), num_eval_envs=cfg.num_eval_envs,
                            episode_length=cfg.eval_episode_length, action_repeat=1, key=key)
