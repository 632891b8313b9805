"""Falls of a training run's checkpoint in its own training environment on a given ground, the command held at
(vx, 0, 0), no pushes and no randomisation: the training environment's view of a terrain, to hold against the
simulator's (`bench_walk_robustness.py --terrain`) when a policy that trained on terrain falls in the simulator.

Run: PYTHONPATH=src python benchmarks/bench_env_terrain.py RUN --terrain rough:height=0.01 [--checkpoint NAME]
     [--terrain-seed 0] [--vx 0.1] [--envs 16] [--seconds 8]
"""

from __future__ import annotations

import argparse
import platform
import time
from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from brax.training.agents.ppo import networks as ppo_networks

from toddlerbot.rl import train
from toddlerbot.rl.export import restore_checkpoint
from toddlerbot.rl.walk_env import WalkEnv
from toddlerbot.rl.wrappers import wrap_for_training


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("run", type=Path)
    parser.add_argument("--terrain", default="flat")
    parser.add_argument("--terrain-seed", type=int, default=0)
    parser.add_argument("--checkpoint", default=None, help="a file of RUN/checkpoints (default: the latest)")
    parser.add_argument("--vx", type=float, default=0.1)
    parser.add_argument("--envs", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=8.0)
    args = parser.parse_args()

    env_cfg, ppo_cfg = train.load_config(args.run)
    calm = replace(env_cfg.randomization, push_velocity=0.0, push_velocity_min=0.0)
    env = WalkEnv(replace(env_cfg, terrain=args.terrain, terrain_seed=args.terrain_seed, randomize=False,
                          randomization=calm))
    paths = train.checkpoint_paths(args.run)
    path = args.run / "checkpoints" / args.checkpoint if args.checkpoint else paths[-1]
    state, _ = restore_checkpoint(path, ppo_cfg)
    networks = train.make_networks(env.observation_size, env.action_size, ppo_cfg)
    policy = ppo_networks.make_inference_fn(networks)((state.normalizer_params, state.params.policy),
                                                      deterministic=True)
    batched = wrap_for_training(env, ppo_cfg.episode_length)
    reset, step, act = jax.jit(batched.reset), jax.jit(batched.step), jax.jit(lambda o, k: policy(o, k)[0])
    s = reset(jax.random.split(jax.random.PRNGKey(0), args.envs))
    command = jnp.tile(jnp.asarray([args.vx, 0.0, 0.0]), (args.envs, 1))
    fall_time = np.full(args.envs, np.nan)
    t0 = time.perf_counter()
    for i in range(round(args.seconds / env_cfg.ctrl_dt)):
        s = step(s.replace(info={**s.info, "command": command}), act(s.obs, jax.random.PRNGKey(i)))
        fell = (np.asarray(s.done) > 0) & (np.asarray(s.info["truncation"]) == 0) & np.isnan(fall_time)
        fall_time[fell] = (i + 1) * env_cfg.ctrl_dt
    falls = np.sort(fall_time[~np.isnan(fall_time)])
    print(f"{args.run.name} {path.name} on {args.terrain} (seed {args.terrain_seed}), vx {args.vx:g} m/s: "
          f"{len(falls)}/{args.envs} fell in {args.seconds:g} s, at {np.round(falls, 2).tolist()} s "
          f"({platform.machine()}, {time.perf_counter() - t0:.0f} s wall)")


if __name__ == "__main__":
    main()
