"""What whole-body contacts cost the motion-tracking environment (`rl train --env track`): env steps per second of a
batch of `TrackEnv`s with ``contacts="all"`` (track's default: every robot geom against the floor and the spec's
self-collision pairs) against walking's ``feet_hands``, and the contacts MuJoCo finds along the motion's reference
with each set. Randomised envs, zero actions (the reference replayed), the same process and machine for both.

    PYTHONPATH=src python benchmarks/bench_track.py                      # CPU backend, squat, 64 envs (a minute)
    PYTHONPATH=src python benchmarks/bench_track.py --backend mjx --envs 1024   # MJX (on a GPU)
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import numpy as np


def bench(contacts: str, args: argparse.Namespace) -> None:
    import jax
    import jax.numpy as jnp
    from mujoco import mjx

    from toddlerbot.rl.track_config import TrackConfig
    from toddlerbot.rl.track_env import TrackEnv
    from toddlerbot.rl.train import describe_device

    env = TrackEnv(replace(TrackConfig(), motion=args.motion, contacts=contacts, backend=args.backend))
    ncon = [d.ncon for d in env.reference.datas(env.mj_model)]
    slots = mjx.make_data(env.mj_model)._impl  # MJX's contacts and constraint rows are fixed by the model
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(0), args.envs))
    zeros = jnp.zeros((args.envs, env.action_size))
    t0 = time.perf_counter()
    state = jax.block_until_ready(step(state, zeros))
    compile_s = time.perf_counter() - t0
    for _ in range(3):
        state = step(state, zeros)
    jax.block_until_ready(state)
    t0 = time.perf_counter()
    for _ in range(args.steps):
        state = step(state, zeros)
    jax.block_until_ready(state)
    rate = args.envs * args.steps / (time.perf_counter() - t0)
    print(f"{contacts:>10}: {rate:8.0f} env steps/s ({args.envs} envs x {args.steps} steps; first step with compile "
          f"{compile_s:.1f} s); contacts along the reference: mean {np.mean(ncon):.1f}, max {max(ncon)}; MJX: "
          f"{slots.contact.geom.shape[0]} contact slots, {slots.efc_J.shape[0]} constraint rows; "
          f"{describe_device(env)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--motion", default="squat")
    parser.add_argument("--backend", choices=("cpu", "mjx"), default="cpu")
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=2, help="Measurements of each set, alternating (the "
                                                                 "machine's load varies).")
    args = parser.parse_args()
    print(f"motion {args.motion}, {args.backend} backend, load average {os.getloadavg()[0]:.2f}")
    for contacts in ("feet_hands", "all") * args.repeats:
        bench(contacts, args)


if __name__ == "__main__":
    main()
