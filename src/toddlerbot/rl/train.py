"""PPO training of the walking policy with Brax's PPO components and fully resumable checkpoints.

Brax's ``ppo.train`` saves only network parameters, so this module runs the same algorithm (Brax's networks,
loss, GAE, running observation statistics and rollout code, Table 5 hyperparameters) in its own loop and
checkpoints the whole `TrainingState`: network parameters, Adam optimiser state, observation normaliser and
the step counter, plus the PRNG key and the metric history. ``resume`` continues a run bit-for-bit from its
last checkpoint except for the environments, which start fresh episodes.

Devices: the epoch is ``jax.pmap``-ed over all JAX devices (``num_envs`` is split between them and gradients and
normaliser statistics are averaged with ``pmean``), so several GPUs on one host are used without changes (select
them with ``CUDA_VISIBLE_DEVICES``), and with `toddlerbot.rl.distributed` the devices of several processes and
machines: each process steps the envs of its own devices, and process 0 alone writes the run directory.

Run directory layout: ``config.json``, ``checkpoints/step_<n>.msgpack``, ``metrics.jsonl``,
``training_curve.png``, ``tensorboard/`` (the same metrics as TensorBoard scalars, `toddlerbot.metrics`).
"""

from __future__ import annotations

import functools
import json
import os
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import flax
import jax
import jax.numpy as jnp
import numpy as np
import optax
from brax.envs.base import Env, State
from brax.training import acting, gradients, types
from brax.training.acme import running_statistics, specs
from brax.training.agents.ppo import losses as ppo_losses
from brax.training.agents.ppo import networks as ppo_networks
from flax import serialization
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_bytes, atomic_write_text
from toddlerbot.metrics import Dashboards, MetricsLogger
from toddlerbot.rl import distributed
from toddlerbot.rl.compilation import compile_clock
from toddlerbot.rl.config import (
    DEFAULT_ENVIRONMENT,
    CommandConfig,
    EnvConfig,
    ImitationConfig,
    ObsConfig,
    PPOConfig,
    RandomizationConfig,
    RewardConfig,
)
from toddlerbot.rl.environment import RLEnvironment
from toddlerbot.rl.environments import environment_class
from toddlerbot.rl.imitation import WarmStart
from toddlerbot.rl.precision import use_full_precision
from toddlerbot.rl.run_files import (
    CHECKPOINTS,
    CONFIG,
    IMITATION_RECORD,
    MAX_CHECKPOINT_BYTES,
    METRICS_RECORD,
    MOTOR_PARAMS_RECORD,
    WARM_START,
    motor_params_record,
    read_json_lines,
    read_payload,
    read_run_text,
)
from toddlerbot.rl.wrappers import wrap_for_training
from toddlerbot.sim.terrain import START
from toddlerbot.yaml_input import read_bytes

AXIS = "devices"
Progress = Callable[[int, int, dict[str, float]], None]
"""progress(env_steps_done, env_steps_total, metrics)."""


@flax.struct.dataclass
class TrainingState:
    optimizer_state: optax.OptState
    """Gradient clipping, then Adam with its (adapted) learning rate as an injected hyperparameter."""
    params: ppo_losses.PPONetworkParams
    normalizer_params: running_statistics.RunningStatisticsState
    env_steps: jax.Array


def make_networks(obs_size: dict, action_size: int, cfg: PPOConfig) -> ppo_networks.PPONetworks:
    """Actor (a Gaussian with a state-independent, learned log standard deviation; actions unsquashed) and
    critic MLPs; the actor sees ``state``, the critic ``privileged_state``."""
    return ppo_networks.make_ppo_networks(
        obs_size, action_size,
        preprocess_observations_fn=running_statistics.normalize if cfg.normalize_observations
        else types.identity_observation_preprocessor,
        policy_hidden_layer_sizes=cfg.policy_hidden, value_hidden_layer_sizes=cfg.value_hidden,
        policy_obs_key="state", value_obs_key="privileged_state",
        distribution_type="normal", noise_std_type="log", init_noise_std=cfg.init_std,
    )


def make_optimizer(cfg: PPOConfig) -> optax.GradientTransformation:
    return optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm),
                       optax.inject_hyperparams(optax.adam)(learning_rate=cfg.learning_rate))


def learning_rate(opt_state: optax.OptState) -> jax.Array:
    """The current Adam step size held in an optimiser state of `make_optimizer`."""
    return opt_state[1].hyperparams["learning_rate"]


def adam_moments(opt_state: optax.OptState) -> optax.ScaleByAdamState:
    """Adam's step count and moments inside an optimiser state of `make_optimizer`."""
    return opt_state[1].inner_state[0]


def with_learning_rate(opt_state: optax.OptState, lr: jax.Array) -> optax.OptState:
    clip, adam = opt_state
    return clip, adam._replace(hyperparams={**adam.hyperparams, "learning_rate": lr})


def adapt_learning_rate(lr: jax.Array, kl: jax.Array, cfg: PPOConfig) -> jax.Array:
    """KL-targeting step size: shrink when the policy moved too far from the behaviour policy, grow when it
    barely moved (``desired_kl`` None: unchanged)."""
    if cfg.desired_kl is None:
        return lr
    lr = jnp.where(kl > 2 * cfg.desired_kl, lr / cfg.lr_factor,
                   jnp.where(kl < cfg.desired_kl / 2, lr * cfg.lr_factor, lr))
    return jnp.clip(lr, *cfg.lr_bounds)


def _initial_state(networks: ppo_networks.PPONetworks, optimizer: optax.GradientTransformation, obs_size: dict,
                   key: jax.Array) -> TrainingState:
    k_policy, k_value = jax.random.split(key)
    params = ppo_losses.PPONetworkParams(policy=networks.policy_network.init(k_policy),
                                         value=networks.value_network.init(k_value))
    obs_spec = {k: specs.Array(v, jnp.dtype("float32")) for k, v in obs_size.items()}
    return TrainingState(optimizer_state=optimizer.init(params), params=params,
                         normalizer_params=running_statistics.init_state(obs_spec),
                         env_steps=jnp.zeros((), jnp.int32))


def scaled_action_head(state: TrainingState, scale: float) -> TrainingState:
    """``state`` with the actor's output layer (the action means) multiplied by ``scale``, so that a fresh policy's
    mean actions are near zero: a residual policy without a warm start then starts on its reference."""
    if scale == 1.0:
        return state
    policy = state.params.policy
    head = jax.tree.map(lambda x: x * scale, policy["params"]["Dense_0"])
    policy = {**policy, "params": {**policy["params"], "Dense_0": head}}
    return state.replace(params=state.params.replace(policy=policy))


class PPO:
    """Brax's PPO pieces (networks, loss with GAE, running observation statistics, rollouts) assembled into one
    ``pmap``-ed training epoch over all local devices, for any Brax ``Env`` whose observation is a dict with
    ``state`` (actor) and ``privileged_state`` (critic).

    Two departures from ``brax.training.agents.ppo.train``, both to keep the update on-policy and bounded:
    the SGD passes use the observation normaliser the rollout's policy used (the statistics are updated with
    the new batch afterwards; Brax updates them first, so even the first minibatch scores its actions under a
    different policy), and the learning rate adapts to a KL target (`adapt_learning_rate`).
    """

    def __init__(self, env: Env, cfg: PPOConfig) -> None:
        self.env, self.cfg = env, cfg
        # num_envs / (every process's devices) envs on each device; this process steps those of its own devices, the
        # rows `_mine` of a per-device batch (`toddlerbot.rl.distributed`)
        self.n_devices, n_global = jax.local_device_count(), jax.device_count()
        if cfg.num_envs % n_global:
            processes = f" of {jax.process_count()} processes" if jax.process_count() > 1 else ""
            raise ToddlerbotError(f"num_envs {cfg.num_envs} is not divisible by the {n_global} JAX devices{processes}")
        self._mine = slice(distributed.first_local_device(), distributed.first_local_device() + self.n_devices)
        self.train_env = wrap_for_training(env, cfg.episode_length)
        self.obs_size = env.observation_size
        self.networks = make_networks(self.obs_size, env.action_size, cfg)
        self.make_policy = ppo_networks.make_inference_fn(self.networks)
        self.optimizer = make_optimizer(cfg)
        if cfg.mirror_loss and not hasattr(env, "mirror_actor_obs"):
            raise ToddlerbotError(f"mirror_loss {cfg.mirror_loss}: the environment {type(env).__name__} has no "
                                  "mirror (mirror_actor_obs, mirror_action)")
        self._ppo_loss = functools.partial(
            ppo_losses.compute_ppo_loss, ppo_network=self.networks, entropy_cost=cfg.entropy_cost,
            discounting=cfg.discounting, reward_scaling=cfg.reward_scaling, gae_lambda=cfg.gae_lambda,
            clipping_epsilon=cfg.clipping_epsilon, normalize_advantage=True,
        )
        self._loss_and_grad = gradients.loss_and_pgrad(self.loss, pmap_axis_name=AXIS, has_aux=True)
        self.rollouts = cfg.batch_size * cfg.num_minibatches // cfg.num_envs
        updates_total = -(-cfg.num_timesteps // cfg.env_steps_per_update)
        self.epochs = max(1, min(cfg.num_evals, updates_total))
        self.updates_per_epoch = -(-updates_total // self.epochs)
        self.total_steps = self.updates_per_epoch * self.epochs * cfg.env_steps_per_update
        self._step_metrics = getattr(env, "step_metrics", ())
        self._p_epoch = jax.pmap(self._epoch, axis_name=AXIS)
        self._p_reset = jax.pmap(self.train_env.reset, axis_name=AXIS)

    def loss(self, params: ppo_losses.PPONetworkParams, normalizer, data: types.Transition, key: jax.Array):
        """Brax's PPO loss with this configuration, plus ``mirror_loss`` x `asymmetry` where that weight is set:
        (params, normaliser, [B, T] batch, key) -> (loss, metrics)."""
        loss, metrics = self._ppo_loss(params, normalizer, data, key)
        if not self.cfg.mirror_loss:
            return loss, metrics
        asymmetry = self.asymmetry(params.policy, normalizer, data.observation)
        return loss + self.cfg.mirror_loss * asymmetry, {**metrics, "mirror_loss": asymmetry}

    def asymmetry(self, policy_params, normalizer, obs: dict) -> jax.Array:
        """Mean over the batch of the squared distance between the policy's mean action and the mirror image of
        its mean action on the mirrored observation: 0 for a policy that is its own mirror image (the mirror
        symmetry loss of Yu, Turk and Liu, SIGGRAPH 2018)."""
        apply = functools.partial(self.networks.policy_network.apply, normalizer, policy_params)
        action, _ = apply(obs)  # the Gaussian's (mean, std) (`make_networks`)
        mirrored, _ = apply({**obs, "state": self.env.mirror_actor_obs(obs["state"])})
        return jnp.mean(jnp.sum(jnp.square(action - self.env.mirror_action(mirrored)), axis=-1))

    def initial_state(self, key: jax.Array) -> TrainingState:
        return scaled_action_head(_initial_state(self.networks, self.optimizer, self.obs_size, key),
                                  self.cfg.init_action_scale)

    def reset(self, key: jax.Array) -> State:
        """Fresh batched environments, split over the devices (this process's share of them)."""
        keys = jax.random.split(key, self.cfg.num_envs).reshape(jax.device_count(), -1, *key.shape)
        return self._p_reset(keys[self._mine])

    def epoch(self, ts: TrainingState, env_state: State, key: jax.Array) -> tuple[TrainingState, State, dict]:
        """``updates_per_epoch`` PPO updates; returns the new state, the environments and the epoch's mean
        metrics (floats; ``kl_max`` is the largest per-update mean KL)."""
        # every call's arguments placed alike (replicated, or one shard per device), else each new placement
        # compiles the epoch again, and on several devices is refused
        n = self.n_devices
        # on the host: an eager jnp.broadcast_to compiled once more per leaf when its input's placement changed
        p_ts = _per_device(jax.tree.map(lambda x: np.broadcast_to(np.asarray(x), (n, *np.shape(x))), ts))
        keys = _per_device(jax.random.split(key, jax.device_count())[self._mine])
        p_ts, env_state, metrics = self._p_epoch(p_ts, _strip_weak_types(env_state), keys)
        return jax.tree.map(_first_local, p_ts), env_state, {k: float(_first_local(v)) for k, v in metrics.items()}

    # inside pmap -----------------------------------------------------------------------------------------------
    def _minibatch_step(self, carry, data, normalizer):
        opt_state, params, key = carry
        key, k_loss = jax.random.split(key)
        (_, metrics), grads = self._loss_and_grad(params, normalizer, data, k_loss)
        # KL of the policy before this step against the behaviour policy, agreed over devices
        lr = adapt_learning_rate(learning_rate(opt_state), jax.lax.pmean(metrics["kl_mean"], AXIS), self.cfg)
        opt_state = with_learning_rate(opt_state, lr)
        updates, opt_state = self.optimizer.update(grads, opt_state, params)
        return (opt_state, optax.apply_updates(params, updates), key), {**metrics, "learning_rate": lr}

    def _sgd_pass(self, carry, _, data, normalizer):
        opt_state, params, key = carry
        key, k_perm, k_grad = jax.random.split(key, 3)
        n_mb = self.cfg.num_minibatches
        shuffled = jax.tree.map(lambda x: jax.random.permutation(k_perm, x).reshape((n_mb, -1, *x.shape[1:])), data)
        (opt_state, params, _), metrics = jax.lax.scan(
            functools.partial(self._minibatch_step, normalizer=normalizer), (opt_state, params, k_grad), shuffled)
        return (opt_state, params, key), metrics

    def _update(self, carry, _):
        ts, env_state, key = carry
        cfg = self.cfg
        k_sgd, k_unroll, key = jax.random.split(key, 3)
        policy = self.make_policy((ts.normalizer_params, ts.params.policy, ts.params.value))

        def unroll(c, _):
            state, k = c
            k, k_next = jax.random.split(k)
            state, data = acting.generate_unroll(self.train_env, state, policy, k, cfg.unroll_length,
                                                 extra_fields=("truncation", "episode_metrics", "episode_done"))
            return (state, k_next), data

        (env_state, _), data = jax.lax.scan(unroll, (env_state, k_unroll), None, length=self.rollouts)
        data = jax.tree.map(lambda x: jnp.swapaxes(x, 1, 2), data)
        data = jax.tree.map(lambda x: x.reshape((-1, *x.shape[2:])), data)
        (opt_state, params, _), metrics = jax.lax.scan(
            functools.partial(self._sgd_pass, data=data, normalizer=ts.normalizer_params),
            (ts.optimizer_state, ts.params, k_sgd), None, length=cfg.num_updates_per_batch)
        normalizer = running_statistics.update(ts.normalizer_params, data.observation, pmap_axis_name=AXIS)
        extras = data.extras["state_extras"]
        done = extras["episode_done"]
        n_done = jnp.sum(done)
        metrics = jax.tree.map(jnp.mean, metrics)
        episodes = extras["episode_metrics"]
        lengths = jnp.maximum(jnp.sum(episodes["length"] * done), 1)
        metrics.update(
            episode_reward=jnp.sum(episodes["sum_reward"] * done) / jnp.maximum(n_done, 1),
            episode_length=jnp.sum(episodes["length"] * done) / jnp.maximum(n_done, 1),
            **{name: jnp.sum(episodes[name] * done) / lengths for name in self._step_metrics if name in episodes},
            episodes=n_done, step_reward=jnp.mean(data.reward),
            fall_rate=jnp.sum(done * (1 - extras["truncation"])) / done.size,
        )
        ts = TrainingState(opt_state, params, normalizer, ts.env_steps + cfg.env_steps_per_update)
        return (ts, env_state, key), metrics

    def _epoch(self, ts, env_state, key):
        (ts, env_state, _), metrics = jax.lax.scan(self._update, (ts, env_state, key), None,
                                                   length=self.updates_per_epoch)
        kl_max = jnp.max(metrics["kl_mean"])
        metrics = {**jax.tree.map(jnp.mean, metrics), "kl_max": kl_max,
                   "learning_rate": metrics["learning_rate"][-1]}
        return ts, env_state, jax.tree.map(lambda m: jax.lax.pmean(m, AXIS), metrics)


# configuration files -------------------------------------------------------------------------------------------
def save_config(run_dir: Path, env_cfg: EnvConfig, ppo_cfg: PPOConfig,
                imitation_cfg: ImitationConfig | None = None, stages: list[dict] | None = None) -> None:
    """config.json, the reward weights resolved (`RewardTerms.weights`); ``stages`` (see `training_stages`) where a
    resumed run changed its push band or budget."""
    weights = environment_class(env_cfg.environment).reward_terms.weights(env_cfg.reward.weights)
    env_cfg = replace(env_cfg, reward=replace(env_cfg.reward, weights=weights))
    raw = {"env": asdict(env_cfg), "ppo": asdict(ppo_cfg), "imitation": asdict(imitation_cfg or ImitationConfig())}
    atomic_write_text(run_dir / CONFIG, json.dumps(raw | ({"stages": stages} if stages else {}), indent=1))


def training_stage(from_env_steps: int, env_cfg: EnvConfig, ppo_cfg: PPOConfig) -> dict:
    """One stage of a run: from this PPO env step on, pushes in this band at these intervals, IMU readings this
    old, this ground and this KL target of PPO's step size, until this many env steps."""
    band = env_cfg.randomization
    return {"from_env_steps": int(from_env_steps), "push_velocity": [band.push_velocity_min, band.push_velocity],
            "push_interval_s": list(band.push_interval_s), "imu_age_s": list(band.imu_age_s),
            "terrain": env_cfg.terrain, "terrain_seed": env_cfg.terrain_seed, "terrain_start": env_cfg.terrain_start,
            "desired_kl": ppo_cfg.desired_kl,
            "num_timesteps": ppo_cfg.num_timesteps}


def training_stages(run_dir: Path) -> list[dict]:
    """The run's stages, oldest first: one unless `rl train --resume` changed the pushes, the IMU age, the ground
    or the budget. Stages recorded before a resume could change the push interval ran the configuration's; those
    recorded before the IMU age existed, fresh readings; those before terrains, the flat floor; those before the KL
    target or the start square could change, the configuration's (the start square: `sim.terrain.START`)."""
    raw = json.loads(read_run_text(run_dir / CONFIG, "training configuration"))
    env_cfg, ppo_cfg = load_config(run_dir)
    if "stages" in raw:
        interval = list(env_cfg.randomization.push_interval_s)
        return [{"push_interval_s": interval, "imu_age_s": [0.0, 0.0], "terrain": "flat", "terrain_seed": 0,
                 "terrain_start": START, "desired_kl": ppo_cfg.desired_kl, **stage}
                for stage in raw["stages"]]
    return [training_stage(0, env_cfg, ppo_cfg)]


def stages_until(stages: list[dict], env_steps: int) -> list[dict]:
    """The stages that trained a checkpoint of ``env_steps`` PPO env steps (a stage starting there had not)."""
    return [stage for i, stage in enumerate(stages) if i == 0 or stage["from_env_steps"] < env_steps]


def load_imitation_config(run_dir: Path) -> ImitationConfig:
    """The run's warm-start configuration (none for runs that predate it)."""
    raw = json.loads(read_run_text(run_dir / CONFIG, "training configuration"))
    return ImitationConfig(**raw.get("imitation", {}))


def load_config(run_dir: Path) -> tuple[EnvConfig, PPOConfig]:
    """The run's environment configuration (of the class its environment takes; a run saved before environments
    had names trained ``walk``) and PPO configuration. A reward term added since the run was saved has weight 0
    (the run trained without it)."""
    path = run_dir / CONFIG
    if not path.is_file():
        raise ToddlerbotError(f"{path}: no training run here (config.json missing)")
    tuples = lambda d: {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}  # noqa: E731
    try:
        raw = json.loads(read_run_text(path, "training configuration"))
        env = dict(raw["env"])
        env_class = environment_class(env.get("environment", DEFAULT_ENVIRONMENT))
        reward = tuples(env["reward"])
        env_cfg = env_class.config_class(
            **{k: v for k, v in tuples(env).items() if k not in ("obs", "command", "reward", "randomization")},
            obs=ObsConfig(**env["obs"]), command=CommandConfig(**tuples(env["command"])),
            reward=RewardConfig(**{**reward, "weights": env_class.reward_terms.saved_weights(reward["weights"])}),
            randomization=RandomizationConfig(**tuples(env["randomization"])),
        )
        return env_cfg, PPOConfig(**tuples(raw["ppo"]))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise ToddlerbotError(f"{path}: not a training configuration ({reason})") from None


# checkpoints ----------------------------------------------------------------------------------------------------
def checkpoint_paths(run_dir: Path) -> list[Path]:
    return sorted((run_dir / CHECKPOINTS).glob("step_*.msgpack"))


def checkpoint_env_steps(path: Path) -> int:
    """PPO env steps of a checkpoint, from its name (``step_<n>.msgpack``)."""
    return int(path.stem.removeprefix("step_"))


def save_checkpoint(run_dir: Path, state: TrainingState, key: jax.Array, history: list[dict]) -> Path:
    """Write the full training state atomically (temporary file, then rename)."""
    folder = run_dir / CHECKPOINTS
    folder.mkdir(parents=True, exist_ok=True)
    payload = {"state": serialization.to_state_dict(jax.device_get(state)), "key": np.asarray(jax.device_get(key)),
               "history": json.dumps(history)}
    path = folder / f"step_{int(state.env_steps):012d}.msgpack"
    return atomic_write_bytes(path, serialization.msgpack_serialize(payload))


def load_checkpoint(path: Path, template: TrainingState) -> tuple[TrainingState, jax.Array, list[dict]]:
    payload = read_payload(path)
    try:
        state = serialization.from_state_dict(template, payload["state"])
        key, history = jnp.asarray(payload["key"]), json.loads(payload["history"])
    except Exception as exc:  # msgpack, flax and json raise many types for empty, truncated or foreign bytes
        reason = " ".join(str(exc).split()) or f"{type(exc).__name__}: empty or truncated"
        raise ToddlerbotError(f"{path}: not a checkpoint of this configuration ({reason})") from None
    shapes = [(np.shape(a), np.shape(b)) for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(template),
                                                         strict=True)]
    if any(a != b for a, b in shapes):
        first = next((a, b) for a, b in shapes if a != b)
        raise ToddlerbotError(f"{path}: not a checkpoint of this configuration (array of shape {first[0]} where "
                              f"the networks need {first[1]})")
    if not all(bool(np.all(np.isfinite(np.asarray(leaf)))) for leaf in jax.tree.leaves(state)
               if np.issubdtype(np.asarray(leaf).dtype, np.floating)):
        raise ToddlerbotError(f"{path}: checkpoint holds non-finite parameters (a diverged run); resume from an "
                              "earlier one")
    return state, key, history


# training --------------------------------------------------------------------------------------------------------
def train(run_dir: Path, env_cfg: EnvConfig | None = None, ppo_cfg: PPOConfig | None = None, resume: bool = False,
          progress: Progress | None = None, env: RLEnvironment | None = None, max_epochs: int | None = None,
          time_limit_s: float | None = None, imitation_cfg: ImitationConfig | None = None,
          imitation_progress: Callable[[dict], None] | None = None,
          dashboards: Dashboards | None = None) -> tuple[TrainingState, list[dict]]:
    """Train (or, with ``resume``, continue training) into ``run_dir``; returns the final state and the metric
    history (one dict per epoch). A run with ``imitation_cfg.iterations`` starts with the DAgger warm start
    (`toddlerbot.rl.imitation`, saved as ``warm_start.msgpack``; its records in ``imitation.jsonl``) and PPO
    continues from its actor, critic and normaliser. ``max_epochs`` / ``time_limit_s`` stop this call early
    (after a checkpoint; an epoch is not started when the previous one's duration says it would end past the
    limit); ``resume`` continues from there. Records hold ``walltime``: seconds since the run started, every
    phase included (summed over resumed calls); ``compile_s``: seconds JAX spent compiling PPO's programs since the
    previous record (in a call's first record: the environments' reset and the epoch, from the persistent cache
    where it has them), which ``epoch_seconds`` and ``sps`` (training alone) exclude. Every record goes through
    one `MetricsLogger`: the JSON lines, the TensorBoard scalars ``ppo/<key>`` and ``dagger/<key>`` in
    ``tensorboard/`` and, with ``dashboards.wandb``, W&B (``dashboards`` default: JSON lines and TensorBoard). Their
    x axis is the run's environment steps, the warm start's included (as in ``training_curve.png``)."""
    t_start = time.perf_counter()
    use_full_precision()
    run_dir = Path(run_dir)
    distributed.wait_for_main("rl-train-plan")  # the others read what process 0 alone wrote (a resume's next stage)
    main = distributed.is_main()
    if resume:
        env_cfg, ppo_cfg = load_config(run_dir)
        imitation_cfg = load_imitation_config(run_dir)
    else:
        env_cfg, ppo_cfg = env_cfg or EnvConfig(), ppo_cfg or PPOConfig()
        imitation_cfg = imitation_cfg or ImitationConfig()
    cfg = ppo_cfg
    env = env or environment_class(env_cfg.environment)(env_cfg)
    if not resume and main:
        run_dir.mkdir(parents=True, exist_ok=True)
        save_config(run_dir, env.cfg, ppo_cfg, imitation_cfg)
        env.record_action_space(run_dir)
        if env.cfg.motor_params:
            record = motor_params_record(env.cfg.motor_params)
            atomic_write_text(run_dir / MOTOR_PARAMS_RECORD, json.dumps(record, indent=1))
    if main:
        config = json.loads(read_run_text(run_dir / CONFIG, "training configuration"))
        logger = MetricsLogger.open(run_dir, {"ppo": METRICS_RECORD, "dagger": IMITATION_RECORD}, dashboards,
                                    job_type="rl-train", config=config)
    else:
        logger = MetricsLogger([])  # the other processes write nothing
    with logger as metrics:
        return _train(run_dir, env, cfg, resume, progress, max_epochs, time_limit_s, imitation_cfg,
                      imitation_progress, metrics, t_start)


def _train(run_dir: Path, env: RLEnvironment, cfg: PPOConfig, resume: bool, progress: Progress | None,
           max_epochs: int | None, time_limit_s: float | None, imitation_cfg: ImitationConfig,
           imitation_progress: Callable[[dict], None] | None, metrics: MetricsLogger,
           t_start: float) -> tuple[TrainingState, list[dict]]:
    ppo = PPO(env, cfg)
    distributed.agree("training configuration", json.dumps([asdict(env.cfg), asdict(cfg)], default=str))

    key = jax.random.PRNGKey(cfg.seed)
    key, k_init = jax.random.split(key)
    ts = ppo.initial_state(k_init)
    history: list[dict] = []
    paths = checkpoint_paths(run_dir) if resume else []
    prior_walltime = 0.0
    if paths:
        ts, key, history = load_checkpoint(paths[-1], ts)
        prior_walltime = history[-1]["walltime"] if history else 0.0
    elif imitation_cfg.iterations > 0:
        key, k_warm = jax.random.split(key)
        warm, prior_walltime = _warm_start(run_dir, env, ppo, imitation_cfg, ts, k_warm, t_start, time_limit_s,
                                           imitation_progress, metrics)
        ts = _from_warm_start(ts, warm, ppo)
    elif resume:
        raise ToddlerbotError(f"{run_dir}: no checkpoint to resume from")
    ts, key = distributed.from_main((ts, key))  # one state in every process, whichever copy of a file each read
    main = distributed.is_main()
    evaluator = _evaluator(env, ppo.make_policy, cfg, key) if cfg.num_eval_envs > 0 and main else None

    key, k_env = jax.random.split(key)
    clock = compile_clock()
    compiled = clock.seconds()  # from here on PPO's programs (the warm start's are not)
    env_state = ppo.reset(k_env)
    device = describe_device(env)
    warm_steps = _warm_start_env_steps(run_dir)
    epochs_run, last_epoch = 0, 0.0
    while int(ts.env_steps) < ppo.total_steps:
        elapsed = time.perf_counter() - t_start
        if distributed.decide((max_epochs is not None and epochs_run >= max_epochs) or (
                time_limit_s is not None and elapsed + last_epoch > time_limit_s)):  # process 0's clock
            break
        epochs_run += 1
        key, k_epoch = jax.random.split(key)
        t0, compiling = time.perf_counter(), clock.seconds()
        ts, env_state, epoch_metrics = ppo.epoch(ts, env_state, k_epoch)
        now = clock.seconds()
        last_epoch = time.perf_counter() - t0 - (now - compiling)  # training alone: its compilation excluded
        steps = int(ts.env_steps)
        record = {"env_steps": steps, "epoch_seconds": last_epoch, "compile_s": now - compiled,
                  "walltime": prior_walltime + time.perf_counter() - t_start, "device": device,
                  "sps": ppo.updates_per_epoch * cfg.env_steps_per_update / last_epoch, **epoch_metrics}
        if evaluator is not None:
            eval_metrics = evaluator.run_evaluation((ts.normalizer_params, ts.params.policy, ts.params.value), {})
            record.update({k: float(v) for k, v in eval_metrics.items() if np.ndim(v) == 0})
        compiled = now
        history.append(record)
        if main:
            save_checkpoint(run_dir, ts, key, history)
        metrics.log("ppo", record, step=warm_steps + steps)
        if progress:
            progress(steps, ppo.total_steps, record)
    return ts, history


"""File in a run directory holding the DAgger warm start (actor, critic, normaliser, its records)."""


def describe_device(env: RLEnvironment) -> str:
    """What trains: JAX's devices, and for the CPU physics backend the CPU and its threads (of each process, in a run
    of several)."""
    processes = f"{jax.process_count()} processes, each " if jax.process_count() > 1 else ""
    if env.backend != "cpu":
        return f"{processes}{jax.local_device_count()} x {jax.local_devices()[0].device_kind}"
    return f"{processes}CPU: {_cpu_name()}, {os.cpu_count()} cores; physics on {env.physics.threads} threads"


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _warm_start(run_dir: Path, env: RLEnvironment, ppo: PPO, cfg: ImitationConfig, ts: TrainingState, key: jax.Array,
                t_start: float, time_limit_s: float | None, progress,
                metrics: MetricsLogger) -> tuple[WarmStart, float]:
    """The run's warm start: loaded from ``warm_start.msgpack`` or made now (DAgger, or from ``cfg.policy``'s export:
    `toddlerbot.rl.policy_start`) and saved. Returns it and the wall time the run spent before this call (the loaded
    warm start's; 0 when made now)."""
    from toddlerbot.rl.imitation import dagger
    from toddlerbot.rl.policy_start import policy_warm_start

    path = run_dir / WARM_START
    template = {"policy": ts.params.policy, "value": ts.params.value, "normalizer": ts.normalizer_params,
                "env_steps": np.zeros((), np.int64)}
    if path.is_file():
        arrays, history = restore_warm_start(path, read_payload(path, "warm start"), template)
        warm = WarmStart(arrays["policy"], arrays["value"], arrays["normalizer"], int(arrays["env_steps"]), history)
        return warm, warm.history[-1]["walltime"] if warm.history else 0.0
    deadline = None if time_limit_s is None else t_start + time_limit_s
    main = distributed.is_main()  # every process makes it (the same work at once); process 0 writes it
    if main:
        (run_dir / IMITATION_RECORD).unlink(missing_ok=True)  # an interrupted warm start starts over

    def record(m: dict) -> None:
        metrics.log("dagger", m, step=m["env_steps"])
        if progress:
            progress(m)

    make = policy_warm_start if cfg.policy else dagger
    warm = make(env, ppo.networks, cfg, ppo.cfg.episode_length, ppo.cfg.discounting, key, deadline, record,
                t_start=t_start)
    arrays = {"policy": warm.policy, "value": warm.value, "normalizer": warm.normalizer,
              "env_steps": np.asarray(warm.env_steps, np.int64)}
    state = serialization.to_state_dict(jax.device_get(arrays))
    if main:
        atomic_write_bytes(path, serialization.msgpack_serialize({"warm": state,
                                                                  "history": json.dumps(warm.history)}))
    return warm, 0.0  # made in this call: its time is part of this call's wall time


def restore_warm_start(path: Path, payload: dict, template: dict) -> tuple[dict, list[dict]]:
    """(the warm start's arrays in `template`'s structure, its DAgger records) from its file's `payload`
    (`read_payload`), or one line naming the file."""
    try:
        return serialization.from_state_dict(template, payload["warm"]), json.loads(payload["history"])
    except Exception as exc:  # flax and json raise many types for a foreign structure
        raise ToddlerbotError(f"{path}: not a warm start of this configuration "
                              f"({' '.join(str(exc).split())[:200] or type(exc).__name__})") from None


@dataclass(frozen=True)
class WarmStartSource:
    """A finished run whose DAgger warm start another run starts from (``rl train --warm-start``)."""

    run_dir: Path
    env: EnvConfig
    ppo: PPOConfig
    imitation: ImitationConfig

    def policy_of(self, base: PPOConfig) -> PPOConfig:
        """``base`` with the warm start's networks, exploration noise and observation normalisation."""
        return replace(base, policy_hidden=self.ppo.policy_hidden, value_hidden=self.ppo.value_hidden,
                       init_std=self.ppo.init_std, normalize_observations=self.ppo.normalize_observations)


def warm_start_source(run_dir: Path) -> WarmStartSource:
    """The run at ``run_dir`` as a warm start to train from (one-line errors for a folder without one)."""
    if not (run_dir / WARM_START).is_file():
        raise ToddlerbotError(f"--warm-start {run_dir}: no DAgger warm start there ({WARM_START} missing)")
    env, ppo = load_config(run_dir)
    return WarmStartSource(run_dir, env, ppo, load_imitation_config(run_dir))


def adopt_warm_start(source_dir: Path, run_dir: Path) -> None:
    """Copy the warm start and its records into ``run_dir``: `train` then starts PPO from it."""
    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(run_dir / WARM_START, read_bytes(source_dir / WARM_START, "warm start", ToddlerbotError,
                                                        MAX_CHECKPOINT_BYTES))
    records = source_dir / IMITATION_RECORD
    if records.is_file():
        atomic_write_text(run_dir / IMITATION_RECORD, read_run_text(records, "DAgger record"))


def _warm_start_env_steps(run_dir: Path) -> int:
    """Environment steps of the run's warm start (its last record in ``imitation.jsonl``; 0 without one)."""
    records = read_json_lines(run_dir / IMITATION_RECORD, "DAgger record")
    return int(records[-1]["env_steps"]) if records else 0


def _from_warm_start(ts: TrainingState, warm: WarmStart, ppo: PPO) -> TrainingState:
    """PPO's first state: the warm start's networks and normaliser, a fresh optimiser."""
    params = ppo_losses.PPONetworkParams(policy=warm.policy, value=warm.value)
    return ts.replace(params=params, optimizer_state=ppo.optimizer.init(params), normalizer_params=warm.normalizer)


def _per_device(tree):
    """``tree``'s arrays, one row of their leading axis on each of this process's devices: how ``pmap`` places its
    inputs and outputs (what `jax.device_put_replicated` and `jax.device_put_sharded` did; JAX deprecated them in
    0.8.1)."""
    sharding = NamedSharding(Mesh(np.array(jax.local_devices()), (AXIS,)), PartitionSpec(AXIS))
    return jax.device_put(tree, sharding)


def _first_local(x: jax.Array) -> jax.Array:
    """The first of this process's rows of a replicated ``pmap`` output (of several processes, only its own rows are
    addressable)."""
    return jnp.reshape(x.addressable_shards[0].data, x.shape[1:])


def _strip_weak_types(tree):
    """The same arrays without JAX's weak-type flag, so that a jitted function sees one signature every call."""
    return jax.tree.map(lambda x: jnp.asarray(x).astype(jnp.asarray(x).dtype), tree)


def _evaluator(env: RLEnvironment, make_policy, cfg: PPOConfig, key: jax.Array) -> acting.Evaluator:
    return acting.Evaluator(wrap_for_training(env, cfg.eval_episode_length),
                            functools.partial(make_policy, deterministic=True), num_eval_envs=cfg.num_eval_envs,
                            episode_length=cfg.eval_episode_length, action_repeat=1, key=key)
