"""Warm start by imitation: walk-zmp (the closed-loop teacher) labels the states the student visits in the
training environment (DAgger), and the student's actor is fitted to the labels (behaviour cloning).

The teacher is `toddlerbot.policies.walk_zmp.WalkZMPPolicy`, one instance per environment, fed from the env's
noise-free state (joint angles, IMU orientation and gyro) and started with the env's episodes (a zero-command
start, so its left foot stands first, in phase with the tabulated reference; `toddlerbot.rl.reference`). Its
motor targets expressed in the policy's action space, (teacher leg targets - reference) / ``action_scale``
(`teacher_action`), are the labels; its leg gain schedule is the environment's (`teacher_gain_scales`).
"""

from __future__ import annotations

import copy
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import optax
from brax.training.acme import running_statistics, specs
from brax.training.agents.ppo import networks as ppo_networks

from toddlerbot.policies.walk_zmp import WalkZMPPolicy
from toddlerbot.rl.config import ImitationConfig
from toddlerbot.rl.wrappers import wrap_for_training
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

NORMALIZER_STD_MIN = 0.01
"""Smallest standard deviation of the warm start's observation normaliser (normalised units per input unit)."""


def _teacher(description: RobotDescription) -> WalkZMPPolicy:
    # the robot only serves the policy's construction (description, gains, control period)
    return WalkZMPPolicy(MuJoCoRobot(description))


def teacher_gain_scales(description: RobotDescription) -> tuple[np.ndarray, np.ndarray]:
    """walk-zmp's leg gain schedule as factors on the spec's P gains: (stance (n_motors,), swing (2, n_motors),
    0 where a motor is not the swinging leg's)."""
    teacher = _teacher(description)
    default = np.asarray(description.default_kp, dtype=float)
    return teacher.kp / default, teacher.swing_kp / default


def teacher_action(teacher_targets: np.ndarray, ref_leg: np.ndarray, leg_index: np.ndarray,
                   action_scale: float) -> np.ndarray:
    """The residual action (clipped to [-1, 1]) whose leg targets are the teacher's: (teacher - reference) /
    scale."""
    return np.clip((teacher_targets[..., leg_index] - ref_leg) / action_scale, -1.0, 1.0)


@dataclass
class TeacherBatch:
    """One walk-zmp per environment of a batch."""

    policies: list[WalkZMPPolicy]
    joint_matrix: np.ndarray
    """Transmission matrix (joint angles = matrix @ motor angles)."""

    @classmethod
    def build(cls, description: RobotDescription, n: int) -> TeacherBatch:
        proto = _teacher(description)
        return cls([copy.deepcopy(proto) for _ in range(n)], np.asarray(description.transmission.matrix))

    def act(self, restart: np.ndarray, time: np.ndarray, command: np.ndarray, motor_pos: np.ndarray,
            imu_quat: np.ndarray, gyro: np.ndarray) -> np.ndarray:
        """Motor targets (n, n_motors) rad of every env's teacher for the env state after its latest step;
        ``restart[i]``: env i starts a new episode with this state (its teacher starts over)."""
        out = np.zeros_like(motor_pos, dtype=float)
        zeros = np.zeros(motor_pos.shape[1])
        for i, policy in enumerate(self.policies):
            q = np.asarray(motor_pos[i], dtype=float)
            obs = Observation(time=float(time[i]), motor_pos=q, motor_vel=zeros, motor_torque=zeros,
                              joint_pos=self.joint_matrix @ q, joint_vel=zeros,
                              imu_quat=np.asarray(imu_quat[i], dtype=float), imu_ang_vel=np.asarray(gyro[i], float),
                              imu_lin_acc=np.zeros(3), foot_contact=np.zeros(2, dtype=bool))
            if restart[i]:
                policy.reset(obs)
                policy.walk_state = policy.walk.start()  # zero-command start: the reference's leading foot
            out[i] = policy.act(obs, np.asarray(command[i], dtype=float)).motor_targets
        return out


@dataclass
class WarmStart:
    """The result of `dagger`: actor and critic parameters, the observation normaliser, env steps taken, and one
    metrics record per iteration."""

    policy: dict
    value: dict
    normalizer: running_statistics.RunningStatisticsState
    env_steps: int
    history: list[dict]


def dagger(env, networks: ppo_networks.PPONetworks, cfg: ImitationConfig, episode_length: int, discounting: float,
           key: jax.Array, deadline: float | None = None, progress: Callable[[dict], None] | None = None,
           t_start: float | None = None) -> WarmStart:
    """DAgger from walk-zmp in ``env`` (a `toddlerbot.rl.walk_env.WalkEnv`): each iteration steps ``cfg.num_envs`` envs
    for ``cfg.steps`` control steps (the teacher acting in the first ``teacher_iterations``, the student's mean
    after), labels every visited state with the teacher's action, updates the observation normaliser, and fits
    the actor's mean to all labels so far (mean squared error) and the critic to the discounted returns.
    ``deadline`` (``time.perf_counter()`` value) stops after the iteration that passes it; records' ``walltime``
    counts from ``t_start`` (default: now)."""
    train_env = wrap_for_training(env, episode_length)
    reset, step = jax.jit(train_env.reset), jax.jit(train_env.step)
    reference = jax.jit(jax.vmap(env.reference_at))
    mean_action = jax.jit(lambda norm, params, obs: networks.policy_network.apply(norm, params, obs)[0])
    teacher = TeacherBatch.build(env.description, cfg.num_envs)
    k_policy, k_value, k_env, k_seed = jax.random.split(key, 4)
    seed = int(jax.random.randint(k_seed, (), 0, 2**30))
    policy = networks.policy_network.init(k_policy)
    value = networks.value_network.init(k_value)
    obs_spec = {k: specs.Array(v, jnp.dtype("float32")) for k, v in env.observation_size.items()}
    normalizer = running_statistics.init_state(obs_spec)
    fit_policy = fitter(lambda p, norm, obs: networks.policy_network.apply(norm, p, obs)[0], cfg)
    fit_value = fitter(lambda p, norm, obs: networks.value_network.apply(norm, p, obs)[..., None], cfg)
    state = reset(jax.random.split(k_env, cfg.num_envs))
    data: dict[str, list[np.ndarray]] = {"state": [], "privileged_state": [], "label": [], "return": []}
    leg, scale = env.leg_index, env.cfg.obs.action_scale
    history: list[dict] = []
    env_steps, t_start = 0, time.perf_counter() if t_start is None else t_start
    switch = sys.getswitchinterval()
    sys.setswitchinterval(2e-4)  # the physics threads need the GIL between mj_steps while the teacher runs
    try:
        for iteration in range(cfg.iterations):
            teacher_drives = iteration < cfg.teacher_iterations
            obs_it, labels, rewards, dones = [], [], [], []
            for _ in range(cfg.steps):
                info = jax.device_get({k: state.info[k] for k in ("time", "command", "sensors")})
                obs = state.obs
                if not teacher_drives:  # the student acts; the teacher labels while the physics runs
                    action = mean_action(normalizer, policy, obs)
                    next_state = step(state, action)
                s = info["sensors"]
                targets = teacher.act(info["time"] < 1e-6, info["time"], info["command"], s.motor_pos, s.imu_quat,
                                      s.gyro)
                ref_leg, _ = reference(jnp.asarray(info["command"]), jnp.asarray(info["time"]))
                label = teacher_action(targets, np.asarray(ref_leg), leg, scale)
                if teacher_drives:
                    next_state = step(state, jnp.asarray(label, jnp.float32))
                obs_it.append(jax.device_get(obs))
                labels.append(label)
                state = next_state
                rewards.append(np.asarray(state.reward))
                dones.append(np.asarray(state.done))
            env_steps += cfg.num_envs * cfg.steps
            batch = {k: np.stack([o[k] for o in obs_it]) for k in ("state", "privileged_state")}
            # a floor on the std: an input that has not varied yet (e.g. no push so far) must not blow up later
            normalizer = running_statistics.update(normalizer, jax.tree.map(jnp.asarray, batch),
                                                   std_min_value=NORMALIZER_STD_MIN)
            returns = discounted_returns(np.stack(rewards), np.stack(dones), discounting)
            for k in ("state", "privileged_state"):
                data[k].append(batch[k].reshape(-1, batch[k].shape[-1]))
            data["label"].append(np.stack(labels).reshape(-1, len(leg)).astype(np.float32))
            data["return"].append(returns.reshape(-1, 1).astype(np.float32))
            stacked = {k: np.concatenate(v) for k, v in data.items()}
            policy, bc_loss = fit_policy(policy, normalizer, stacked["state"], stacked["label"], seed + 2 * iteration)
            # the returns of the last ~2/(1 - discount) steps of each iteration lack their future: leave them out
            keep = with_future(cfg.steps, discounting, cfg.num_envs)(len(data["return"]))
            value, value_loss = fit_value(value, normalizer, stacked["privileged_state"][keep], stacked["return"][keep],
                                          seed + 2 * iteration + 1)
            dones_it = np.stack(dones)
            record = {"iteration": iteration + 1, "env_steps": env_steps, "walltime": time.perf_counter() - t_start,
                      "teacher_drives": teacher_drives, "bc_loss": bc_loss, "value_loss": value_loss,
                      "fall_rate": float(dones_it.mean()), "step_reward": float(np.mean(rewards)),
                      "samples": len(stacked["label"])}
            history.append(record)
            if progress:
                progress(record)
            if deadline is not None and time.perf_counter() > deadline:
                break
    finally:
        sys.setswitchinterval(switch)
    return WarmStart(policy, value, normalizer, env_steps, history)


def discounted_returns(rewards: np.ndarray, dones: np.ndarray, discounting: float) -> np.ndarray:
    """(T, n) returns-to-go within the chunk, cut at episode ends."""
    out = np.zeros_like(rewards)
    running = np.zeros(rewards.shape[1])
    for t in range(len(rewards) - 1, -1, -1):
        running = rewards[t] + discounting * running * (1.0 - dones[t])
        out[t] = running
    return out


def with_future(steps: int, discounting: float, n_envs: int) -> Callable[[int], np.ndarray]:
    """Row selector of the aggregated (iteration, step, env) returns whose step has 2/(1 - discount) steps after
    it in its iteration."""
    usable = max(1, steps - round(2 / (1 - discounting)))
    rows = (np.arange(steps) < usable).repeat(n_envs)
    return lambda iterations: np.tile(rows, iterations)


def fitter(apply: Callable, cfg: ImitationConfig):
    """fit(params, normaliser, inputs, targets, seed) -> (params, last minibatch loss): ``cfg.bc_steps`` Adam
    steps of mean squared error on random minibatches (a fresh Adam state per call)."""
    optimizer = optax.adam(cfg.learning_rate)

    @jax.jit
    def sgd(params, opt_state, normalizer, x, y):
        def loss(p):
            obs = {"state": x, "privileged_state": x}  # each network reads its own key
            return jnp.mean(jnp.sum((apply(p, normalizer, obs) - y) ** 2, axis=-1))

        value, grads = jax.value_and_grad(loss)(params)
        updates, opt_state = optimizer.update(grads, opt_state, params)
        return optax.apply_updates(params, updates), opt_state, value

    def fit(params, normalizer, inputs: np.ndarray, targets: np.ndarray, seed: int):
        rng = np.random.default_rng(seed)
        opt_state = optimizer.init(params)
        loss = jnp.zeros(())
        for _ in range(cfg.bc_steps):
            rows = rng.integers(0, len(inputs), cfg.batch_size)
            params, opt_state, loss = sgd(params, opt_state, normalizer, jnp.asarray(inputs[rows]),
                                          jnp.asarray(targets[rows]))
        return params, float(loss)

    return fit
