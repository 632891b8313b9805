"""Export a trained policy to the framework-free ``.npz`` read by `toddlerbot.policies.rl_inference`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_savez
from toddlerbot.policies.rl_inference import ACTION_DISTRIBUTION, LEG_GROUP
from toddlerbot.rl.config import EnvConfig, PPOConfig
from toddlerbot.rl.reference import leg_motor_indices
from toddlerbot.rl.run_files import (
    ACTION_SPACE,
    IMITATION_RECORD,
    MOTOR_PARAMS_RECORD,
    REFERENCE_RECORD,
    WARM_START,
    payload_entry,
    read_json_lines,
    read_payload,
    read_run_text,
)
from toddlerbot.robot.description import RobotDescription


def policy_arrays(policy_params: dict, normalizer_params, normalize: bool, obs_size: int) -> dict[str, np.ndarray]:
    """Actor MLP layers (hidden layers, then the action-mean head), the policy's standard deviation and the
    actor-observation normalisation as numpy arrays."""
    params = policy_params["params"]
    hidden = params["MLP_0"]
    names = sorted(hidden, key=lambda n: int(n.rsplit("_", 1)[1]))
    layers = [hidden[n] for n in names] + [params["Dense_0"]]
    arrays = {"distribution": np.array(ACTION_DISTRIBUTION),
              "action_std": np.exp(np.asarray(params["std_logparam"]["log_value"], dtype=np.float32))}
    for i, layer in enumerate(layers):
        arrays[f"layer{i}_kernel"] = np.asarray(layer["kernel"], dtype=np.float32)
        arrays[f"layer{i}_bias"] = np.asarray(layer["bias"], dtype=np.float32)
    if normalize:
        arrays["obs_mean"] = np.asarray(normalizer_params.mean["state"], dtype=np.float32)
        arrays["obs_std"] = np.asarray(normalizer_params.std["state"], dtype=np.float32)
    else:
        arrays["obs_mean"], arrays["obs_std"] = np.zeros(obs_size, np.float32), np.ones(obs_size, np.float32)
    return arrays


def write_policy(path: Path, arrays: dict[str, np.ndarray], env_cfg: EnvConfig, meta: dict,
                 description: RobotDescription, action_space: dict[str, np.ndarray] | None = None) -> Path:
    """Write the export file (atomically) for a robot. ``action_space``: the run's reference and gain-scale arrays
    (`ACTION_SPACE`); the file keeps the reference when the env was residual and the gain schedule when it used
    the teacher's gains. The trained command ranges and the robot's spec variant go into the metadata."""
    if env_cfg.obs.gait_period is None:
        raise ValueError("the observation config to export has no gait period (resolve it with WalkEnv first)")
    action_space = action_space or {}
    if env_cfg.residual:
        arrays = {**arrays, **{k: v for k, v in action_space.items() if k.startswith("ref_")}}
    if env_cfg.teacher_gains:
        arrays = {**arrays, **{k: v for k, v in action_space.items() if k.startswith("kp_")}}
    c = env_cfg.command
    meta = {**meta, "command_low": [c.vx[0], c.vy[0], c.yaw[0]], "command_high": [c.vx[1], c.vy[1], c.yaw[1]],
            "variant": description.spec.variant}
    return atomic_savez(path, {**arrays, **robot_arrays(description), "obs_config": np.array(env_cfg.obs.to_json()),
                               "meta": np.array(json.dumps(meta))})


def robot_arrays(description: RobotDescription) -> dict[str, np.ndarray]:
    """What every exported policy records of its robot: the home pose, the motors' names and the leg motors."""
    return {"home_motor_pos": np.asarray(description.home_motor_pos),
            "leg_motor_index": leg_motor_indices(description), "motor_names": np.array(description.motor_names),
            "leg_motors": np.array(description.group_names(LEG_GROUP))}


def export_run(run_dir: Path, out: Path, description: RobotDescription | None = None,
               checkpoint: str | None = None, extra_meta: dict | None = None) -> Path:
    """Export a checkpoint of a training run (for the run's robot: packaged spec, its variant and params.json):
    the latest, the named file of ``checkpoints/``, or ``warm_start`` (the DAgger warm start, before PPO). The run's
    environment (`toddlerbot.rl.environments`) adds what its runtime policy needs (`RLEnvironment.write_export`);
    ``extra_meta`` goes into the metadata too (e.g. how the checkpoint was selected)."""
    from toddlerbot.rl import train  # jax-heavy; keep `write_policy` importable alone
    from toddlerbot.rl.environment import training_description
    from toddlerbot.rl.environments import environment_class

    run_dir = Path(run_dir)
    env_cfg, ppo_cfg = train.load_config(run_dir)
    environment = environment_class(env_cfg.environment)
    paths = train.checkpoint_paths(run_dir)
    if checkpoint not in (None, "warm_start"):
        paths = [p for p in paths if p.name == checkpoint]
    description = description or training_description(env_cfg)
    warm = _imitation_record(run_dir)
    if checkpoint == "warm_start":
        params, normalizer, steps, history = _warm_start_params(run_dir, ppo_cfg)
        name, warm = WARM_START, []
    else:
        if not paths:
            raise ToddlerbotError(f"{run_dir}: no checkpoint {checkpoint or ''} to export")
        state, history = restore_checkpoint(paths[-1], ppo_cfg)
        params, normalizer, steps, name = state.params.policy, state.normalizer_params, int(state.env_steps), \
            paths[-1].name
    arrays = policy_arrays(params, normalizer, ppo_cfg.normalize_observations,
                           np.shape(params["params"]["MLP_0"]["hidden_0"]["kernel"])[0])
    last = history[-1] if history else {}
    stages = train.stages_until(train.training_stages(run_dir), steps)
    record = run_dir / MOTOR_PARAMS_RECORD
    meta = {"ctrl_dt": env_cfg.ctrl_dt, "environment": env_cfg.environment,
            "runtime_policy": environment.runtime_policy, "reference": run_reference_source(run_dir),
            "run": run_dir.name, "checkpoint": name, "ppo_env_steps": steps,
            "imitation_env_steps": warm[-1]["env_steps"] if warm else 0,
            "env_steps": steps + (warm[-1]["env_steps"] if warm else 0),
            "walltime_s": last.get("walltime"), "episode_reward": last.get("episode_reward"),
            "episode_length": last.get("episode_length"),
            "step_reward": last.get("step_reward"), "sps": last.get("sps"), "device": last.get("device"),
            "backend": env_cfg.backend, "residual": env_cfg.residual, "teacher_gains": env_cfg.teacher_gains,
            "imitation_iterations": len(warm), "policy_hidden": list(ppo_cfg.policy_hidden),
            "num_envs": ppo_cfg.num_envs, "mirror_loss": ppo_cfg.mirror_loss, "seed": ppo_cfg.seed,
            "upper_body_pose": env_cfg.randomization.upper_body_pose,
            "hand_force": env_cfg.randomization.hand_force,
            "push_velocity": stages[-1]["push_velocity"],
            "push_interval_s": stages[-1]["push_interval_s"],
            "reward_weights": env_cfg.reward.weights,
            "push_stages": [[stage["from_env_steps"], *stage["push_velocity"]] for stage in stages],
            "push_interval_stages": [[stage["from_env_steps"], *stage["push_interval_s"]] for stage in stages],
            "imu_age_s": stages[-1]["imu_age_s"],
            "imu_age_stages": [[stage["from_env_steps"], *stage["imu_age_s"]] for stage in stages],
            "terrain": stages[-1]["terrain"],
            "terrain_stages": [[stage["from_env_steps"], stage["terrain"], stage["terrain_seed"]] for stage in stages],
            "terrain_start_stages": [[stage["from_env_steps"], stage["terrain_start"]] for stage in stages],
            "desired_kl_stages": [[stage["from_env_steps"], stage["desired_kl"]] for stage in stages],
            "init_policy": train.load_imitation_config(run_dir).policy,
            "motor_params": json.loads(read_run_text(record, "motor record")) if record.is_file() else [],
            **(extra_meta or {})}
    space = run_dir / ACTION_SPACE
    action_space = dict(np.load(space, allow_pickle=False)) if space.is_file() else None
    return environment.write_export(out, arrays, env_cfg, meta, description, action_space)


def _warm_start_params(run_dir: Path, ppo_cfg: PPOConfig):
    """(actor parameters, normaliser, env steps, records) of the run's DAgger warm start."""

    from toddlerbot.rl import train

    path = run_dir / WARM_START
    if not path.is_file():
        raise ToddlerbotError(f"{run_dir}: no warm start to export")
    payload = read_payload(path, "warm start")
    state, _ = _template(ppo_cfg, *_network_widths(path, payload, ("warm", "normalizer"), ("warm", "policy"),
                                                   "warm start"))
    template = {"policy": state.params.policy, "value": state.params.value, "normalizer": state.normalizer_params,
                "env_steps": np.zeros((), np.int64)}
    arrays, records = train.restore_warm_start(path, payload, template)
    return arrays["policy"], arrays["normalizer"], int(arrays["env_steps"]), records


def _imitation_record(run_dir: Path) -> list[dict]:
    return read_json_lines(run_dir / IMITATION_RECORD, "DAgger record")


def run_reference_source(run_dir: Path) -> str | None:
    """The reference source ("zmp" or "standing") a run recorded, if any."""
    path = Path(run_dir) / REFERENCE_RECORD
    return read_run_text(path, "reference record").strip() if path.is_file() else None


def restore_checkpoint(path: Path, ppo_cfg: PPOConfig):
    """(TrainingState, metric history) of a checkpoint written with this PPO configuration."""

    from toddlerbot.rl import train

    # the networks' input and output widths are read back from the checkpoint
    payload = read_payload(path)
    widths = _network_widths(path, payload, ("state", "normalizer_params"), ("state", "params", "policy"))
    template, _ = _template(ppo_cfg, *widths)
    state, _, history = train.load_checkpoint(path, template)
    return state, history


def _template(ppo_cfg: PPOConfig, obs_size: dict[str, tuple[int, ...]], n_actions: int):
    import jax

    from toddlerbot.rl import train

    networks = train.make_networks(obs_size, n_actions, ppo_cfg)
    return train._initial_state(networks, train.make_optimizer(ppo_cfg), obs_size, jax.random.PRNGKey(0)), networks


def _network_widths(path: Path, payload: dict, normalizer: tuple[str, ...], policy: tuple[str, ...],
                    what: str = "checkpoint") -> tuple[dict[str, tuple[int, ...]], int]:
    """(the actor's and critic's input widths, the number of actions) of a checkpoint (or warm start): the lengths
    of its normaliser's means and of its policy's log standard deviations."""
    widths = []
    for keys in ((*normalizer, "mean", "state"), (*normalizer, "mean", "privileged_state"),
                 (*policy, "params", "std_logparam", "log_value")):
        shape = np.shape(payload_entry(path, payload, keys, what))
        if len(shape) != 1:
            raise ToddlerbotError(f"{path}: not a {what} of a training run ({'/'.join(keys)} has shape {shape})")
        widths.append(int(shape[0]))
    return {"state": (widths[0],), "privileged_state": (widths[1],)}, widths[2]
