"""Export a trained policy to the framework-free ``.npz`` read by `toddlerbot.policies.rl_inference`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.rl_inference import ACTION_DISTRIBUTION, LEG_MOTORS, leg_motor_names
from toddlerbot.rl.config import EnvConfig, PPOConfig
from toddlerbot.rl.reference import home_motor_pos, leg_motor_indices
from toddlerbot.robot.spec import RobotSpec, load_spec


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
                 spec: RobotSpec | None = None) -> Path:
    """Write the export file (atomically) for a robot spec."""
    spec = spec or load_spec()
    if env_cfg.obs.gait_period is None:
        raise ValueError("the observation config to export has no gait period (resolve it with WalkEnv first)")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez(
        tmp, **arrays, home_motor_pos=home_motor_pos(spec), leg_motor_index=leg_motor_indices(spec),
        motor_names=np.array([m.joint for m in spec.motors_by_id]), leg_motors=np.array(leg_motor_names(spec)),
        obs_config=np.array(env_cfg.obs.to_json()), meta=np.array(json.dumps(meta)),
    )
    tmp.replace(path)
    return path


def export_run(run_dir: Path, out: Path) -> Path:
    """Export the latest checkpoint of a training run."""
    from toddlerbot.rl import train  # jax-heavy; keep `write_policy` importable alone

    run_dir = Path(run_dir)
    env_cfg, ppo_cfg = train.load_config(run_dir)
    paths = train.checkpoint_paths(run_dir)
    if not paths:
        raise ToddlerbotError(f"{run_dir}: no checkpoint to export")
    state, history = restore_checkpoint(paths[-1], env_cfg, ppo_cfg)
    obs_size = env_cfg.obs.history * env_cfg.obs.frame_size(len(home_motor_pos(load_spec())))
    arrays = policy_arrays(state.params.policy, state.normalizer_params, ppo_cfg.normalize_observations, obs_size)
    last = history[-1] if history else {}
    meta = {"ctrl_dt": env_cfg.ctrl_dt, "reference": run_reference_source(run_dir), "run": run_dir.name,
            "checkpoint": paths[-1].name, "env_steps": int(state.env_steps),
            "walltime_s": last.get("walltime"), "episode_reward": last.get("episode_reward"),
            "step_reward": last.get("step_reward"), "sps": last.get("sps"),
            "policy_hidden": list(ppo_cfg.policy_hidden)}
    return write_policy(out, arrays, env_cfg, meta)


def run_reference_source(run_dir: Path) -> str | None:
    """The reference source ("zmp" or "standing") a run recorded, if any."""
    path = Path(run_dir) / "reference.txt"
    return path.read_text().strip() if path.is_file() else None


def restore_checkpoint(path: Path, env_cfg: EnvConfig, ppo_cfg: PPOConfig):
    """(TrainingState, metric history) of a checkpoint written with this configuration."""
    import jax

    from toddlerbot.rl import train

    # the critic's input width is read back from the checkpoint
    obs_size = {"state": (env_cfg.obs.history * env_cfg.obs.frame_size(len(home_motor_pos(load_spec()))),),
                "privileged_state": (_critic_width(path),)}
    networks = train.make_networks(obs_size, len(LEG_MOTORS), ppo_cfg)
    template = train._initial_state(networks, train.make_optimizer(ppo_cfg), obs_size, jax.random.PRNGKey(0))
    state, _, history = train.load_checkpoint(path, template)
    return state, history


def _critic_width(path: Path) -> int:
    from flax import serialization

    payload = serialization.msgpack_restore(path.read_bytes())
    return int(np.shape(payload["state"]["normalizer_params"]["mean"]["privileged_state"])[0])
