"""Continue training an exported walk policy (`rl train --init-policy FILE`), e.g. the shipped flat-floor
``walk_rl.npz`` on a terrain.

An export holds the actor and its observation normaliser but no critic. The new run takes the file's settings
(`exported_env_config`, `exported_ppo_config`: rewards, pushes, commands, observations, networks, recorded in its
metadata) and starts PPO from a warm start made of the actor and normaliser as they are and a critic fitted to the
discounted returns the actor earns in the run's own environment (`policy_warm_start`, actor frozen meanwhile), so
that the first PPO updates follow a critic that knows the policy instead of unlearning the policy under a random
one. The warm start is saved like DAgger's (``warm_start.msgpack``, records in ``imitation.jsonl``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from brax.training import types as brax_types
from brax.training.acme import running_statistics, specs
from brax.training.agents.ppo import networks as ppo_networks

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.rl_inference import RLPolicyFile
from toddlerbot.policies.walk_rl import resolve_weights
from toddlerbot.rl.config import EnvConfig, ImitationConfig, PPOConfig, with_num_envs
from toddlerbot.rl.imitation import WarmStart, discounted_returns, fitter, with_future
from toddlerbot.rl.wrappers import wrap_for_training


def exported_policy(policy: str | Path, environment: str) -> RLPolicyFile:
    """The export at ``policy`` (a path, or the name of a shipped policy such as ``walk_rl``), checked to be a
    numpy export of ``environment`` trained without motor parameter files (one line otherwise)."""
    path = resolve_weights(policy)
    exported = RLPolicyFile(path)
    if exported.format != "npz" or exported.environment != environment:
        raise ToddlerbotError(f"--init-policy {path}: expected an .npz export of the {environment!r} environment")
    if exported.meta.get("motor_params"):
        raise ToddlerbotError(f"--init-policy {path}: trained on fitted motor parameters; continuing such a policy "
                              "is not supported (train it from its run with --resume)")
    return exported


def exported_env_config(exported: RLPolicyFile, base: EnvConfig) -> EnvConfig:
    """``base`` with the environment settings the export trained with: its observations, command ranges, reward
    weights, pushes (the last stage's), IMU age, upper-body pose and hand pull, residual actions, gain schedule
    and spec variant."""
    meta = exported.meta
    low, high = meta["command_low"], meta["command_high"]
    command = replace(base.command, **{axis: (low[i], high[i]) for i, axis in enumerate(("vx", "vy", "yaw"))})
    band = replace(base.randomization, push_velocity_min=meta["push_velocity"][0],
                   push_velocity=meta["push_velocity"][1], push_interval_s=tuple(meta["push_interval_s"]),
                   imu_age_s=tuple(meta["imu_age_s"]), upper_body_pose=meta["upper_body_pose"],
                   hand_force=meta["hand_force"])
    return replace(base, obs=exported.obs_config, command=command, randomization=band,
                   reward=replace(base.reward, weights=dict(meta["reward_weights"])), residual=meta["residual"],
                   teacher_gains=meta["teacher_gains"], variant=meta["variant"])


def exported_ppo_config(exported: RLPolicyFile, base: PPOConfig) -> PPOConfig:
    """``base`` with the export's actor widths, environment count and mirror loss."""
    return replace(with_num_envs(base, int(exported.meta["num_envs"])),
                   policy_hidden=tuple(exported.meta["policy_hidden"]), mirror_loss=exported.meta["mirror_loss"])


def actor_params(exported: RLPolicyFile, template: dict) -> dict:
    """The export's actor in the structure of ``template`` (a fresh actor of the run's networks): hidden layers,
    action head and the exploration noise's log standard deviation; one line where a shape differs."""
    network = exported.network
    params = template["params"]
    hidden = sorted(params["MLP_0"], key=lambda n: int(n.rsplit("_", 1)[1]))
    slots = [params["MLP_0"][name] for name in hidden] + [params["Dense_0"]]
    if len(slots) != len(network.kernels):
        raise ToddlerbotError(f"--init-policy {exported.path}: {len(network.kernels)} layers; the run's actor has "
                              f"{len(slots)}")
    layers = []
    for i, (slot, kernel, bias) in enumerate(zip(slots, network.kernels, network.biases)):
        if slot["kernel"].shape != kernel.shape:
            raise ToddlerbotError(f"--init-policy {exported.path}: layer {i} is {kernel.shape}; the run's actor "
                                  f"expects {tuple(slot['kernel'].shape)} (another observation or network width)")
        layers.append({"kernel": jnp.asarray(kernel), "bias": jnp.asarray(bias)})
    log_std = jnp.log(jnp.asarray(exported.action_std, jnp.float32))
    return {"params": {"MLP_0": dict(zip(hidden, layers[:-1])), "Dense_0": layers[-1],
                       "std_logparam": {"log_value": log_std}}}


def _count(n: int) -> brax_types.UInt64:
    return brax_types.UInt64(hi=n >> 32, lo=n & 0xFFFFFFFF)


def _normalizer(state_mean: np.ndarray, state_std: np.ndarray, privileged: running_statistics.RunningStatisticsState,
                count: int) -> running_statistics.RunningStatisticsState:
    """The actor's statistics as exported and the critic's as measured, both weighted as ``count`` samples (the
    env steps the export trained on), so that PPO's updates move them as slowly as the original run's would."""
    mean = {"state": jnp.asarray(state_mean), "privileged_state": privileged.mean["privileged_state"]}
    std = {"state": jnp.asarray(state_std), "privileged_state": privileged.std["privileged_state"]}
    summed = {k: jnp.square(v) * count for k, v in std.items()}
    return privileged.replace(count=_count(count), mean=mean, std=std, summed_variance=summed)


def policy_warm_start(env, networks: ppo_networks.PPONetworks, cfg: ImitationConfig, episode_length: int,
                      discounting: float, key: jax.Array, deadline: float | None = None,
                      progress: Callable[[dict], None] | None = None, t_start: float | None = None) -> WarmStart:
    """The warm start of ``cfg.policy`` in ``env``: ``cfg.iterations`` rollouts of ``cfg.num_envs`` envs for
    ``cfg.steps`` control steps with the export's actor (its actions drawn with its exploration noise, as PPO
    will), the critic's normaliser updated and the critic fitted to all returns so far after each (``cfg.bc_steps``
    Adam steps). ``deadline`` (``time.perf_counter()``) stops after the rollout that passes it."""
    exported = exported_policy(cfg.policy, env.cfg.environment)
    k_policy, k_value, k_env, k_seed, k_act = jax.random.split(key, 5)
    policy = actor_params(exported, networks.policy_network.init(k_policy))
    value = networks.value_network.init(k_value)
    network = exported.network
    measured = running_statistics.init_state(
        {"privileged_state": specs.Array(env.observation_size["privileged_state"], jnp.dtype("float32"))})
    count = int(exported.meta.get("env_steps") or 1)
    normalizer = _normalizer(network.obs_mean, network.obs_std, measured, count)
    train_env = wrap_for_training(env, episode_length)
    reset, step = jax.jit(train_env.reset), jax.jit(train_env.step)
    distribution = networks.parametric_action_distribution
    act = jax.jit(lambda norm, params, obs, k: distribution.postprocess(
        distribution.sample_no_postprocessing(networks.policy_network.apply(norm, params, obs), k)))
    fit_value = fitter(lambda p, norm, obs: networks.value_network.apply(norm, p, obs)[..., None], cfg)
    seed = int(jax.random.randint(k_seed, (), 0, 2**30))
    keep = with_future(cfg.steps, discounting, cfg.num_envs)
    state = reset(jax.random.split(k_env, cfg.num_envs))
    privileged, returns, history = [], [], []
    env_steps, t_start = 0, time.perf_counter() if t_start is None else t_start
    for iteration in range(cfg.iterations):
        obs_it, rewards, dones = [], [], []
        for _ in range(cfg.steps):
            k_act, k_step = jax.random.split(k_act)
            obs_it.append(np.asarray(state.obs["privileged_state"]))
            state = step(state, act(normalizer, policy, state.obs, k_step))
            rewards.append(np.asarray(state.reward))
            dones.append(np.asarray(state.done))
        env_steps += cfg.num_envs * cfg.steps
        batch = np.stack(obs_it)
        measured = running_statistics.update(measured, {"privileged_state": jnp.asarray(batch)})
        normalizer = _normalizer(network.obs_mean, network.obs_std, measured, count)
        privileged.append(batch.reshape(-1, batch.shape[-1]))
        returns.append(discounted_returns(np.stack(rewards), np.stack(dones), discounting).reshape(-1, 1))
        inputs, targets = np.concatenate(privileged), np.concatenate(returns).astype(np.float32)
        rows = keep(len(returns))
        value, value_loss = fit_value(value, normalizer, inputs[rows], targets[rows], seed + iteration)
        dones_it = np.stack(dones)
        record = {"iteration": iteration + 1, "env_steps": env_steps, "walltime": time.perf_counter() - t_start,
                  "value_loss": value_loss, "fall_rate": float(dones_it.mean()), "step_reward": float(np.mean(rewards)),
                  "samples": int(rows.sum())}
        history.append(record)
        if progress:
            progress(record)
        if deadline is not None and time.perf_counter() > deadline:
            break
    return WarmStart(policy, value, normalizer, env_steps, history)
