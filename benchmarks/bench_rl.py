"""RL figures: inference latency of a full-size policy (numpy, and onnxruntime for its ONNX export), and (with
--env) MJX environment JIT-compile time and env steps per second on this machine.

    PYTHONPATH=src python benchmarks/bench_rl.py            # inference only (seconds)
    PYTHONPATH=src python benchmarks/bench_rl.py --env      # + env compile and throughput, MJX vs the CPU
                                                            #   backend in the same run (minutes)
    PYTHONPATH=src python benchmarks/bench_rl.py --ppo-epochs 3 --backend mjx --smoke [--compile-cache]
                                                            # PPO epochs of a recipe: each epoch's compile time
                                                            #   and training time apart (only)
    PYTHONPATH=src python benchmarks/bench_rl.py --tracking walk-rl walk-zmp [--weights F.npz]  # Table 7 errors
                                                            #   on the default and held-out schedules (only)
    PYTHONPATH=src python benchmarks/bench_rl.py --curves recipe=runs/rl/cpu_walk ...   # learning curves (only)
    PYTHONPATH=src python benchmarks/bench_rl.py --solver-cpu   # + each model setting in CPU MuJoCo (float64)
    PYTHONPATH=src python benchmarks/bench_rl.py --settings [I ...] # + 10 s stand, constraint residual, steps/s per
                                                            #   training-model setting (a GPU run: add
                                                            #   --stand-envs 4096)
"""

from __future__ import annotations

import argparse
import itertools
import os
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


def bench_inference(repeats: int = 2000) -> None:
    from toddlerbot.rl.config import CPU, FULL

    for hidden in (FULL.policy_hidden, CPU.policy_hidden):
        _bench_inference(hidden, repeats)


def _bench_inference(hidden: tuple[int, ...], repeats: int) -> None:
    """Per-step time of `RLController.step` (observation, network, reference interpolation) and of the network
    alone, numpy (single-threaded einsum) and, when onnx and onnxruntime are installed, the same policy exported to
    ONNX and run by onnxruntime on one thread; the two are timed alternately so that they share the machine's load."""
    from toddlerbot.policies.rl_inference import GaitReference, ObsConfig, RLController, RLPolicyFile
    from toddlerbot.rl.config import EnvConfig
    from toddlerbot.rl.export import write_policy
    from toddlerbot.robot.description import RobotDescription

    description = RobotDescription.load()
    legs = len(description.groups["leg"])
    obs = ObsConfig(gait_period=0.6)
    n_in = obs.history * obs.frame_size(description.n_motors, legs)
    rng = np.random.default_rng(0)
    sizes = [n_in, *hidden, legs]
    arrays = {}
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        arrays[f"layer{i}_kernel"] = (rng.normal(size=(a, b)) / np.sqrt(a)).astype(np.float32)
        arrays[f"layer{i}_bias"] = np.zeros(b, np.float32)
    arrays["obs_mean"], arrays["obs_std"] = np.zeros(n_in, np.float32), np.ones(n_in, np.float32)
    arrays["distribution"], arrays["action_std"] = np.array("normal"), np.full(legs, 0.5, np.float32)
    controllers = {}
    with tempfile.TemporaryDirectory() as tmp:
        # a residual policy: the reference (the default grid's shape) is interpolated every step
        reference = GaitReference(np.linspace(-0.1, 0.15, 6), np.linspace(-0.08, 0.08, 5), np.linspace(-0.4, 0.4, 5),
                                  0.6, rng.normal(size=(6, 5, 5, 30, legs)), np.ones((6, 5, 5, 30, 2)))
        space = {**reference.arrays(), "kp_stance_scale": np.ones(30), "kp_swing_scale": np.zeros((2, 30))}
        path = write_policy(Path(tmp) / "p.npz", arrays, EnvConfig(obs=obs), {}, description, space)
        controllers["numpy"] = RLController(RLPolicyFile(path))
        try:
            from toddlerbot.rl.onnx_export import export_onnx

            onnx_path, report = export_onnx(path, Path(tmp) / "p.onnx", record_steps=0)
            controllers["onnxruntime"] = RLController(RLPolicyFile(onnx_path))
            onnx_note = f"ONNX vs numpy max abs action difference {report['random']:.1g}"
        except Exception as exc:  # onnx or onnxruntime not installed: the numpy figure alone
            onnx_note = f"onnxruntime skipped: {' '.join(str(exc).split())}"
    home = controllers["numpy"].policy.home_motor_pos
    quat = np.array([1.0, 0, 0, 0])
    x = np.random.default_rng(1).normal(size=(repeats, n_in)).astype(np.float32)
    for ctrl in controllers.values():
        for _ in range(50):
            ctrl.step(0.0, np.zeros(3), home, np.zeros(30), np.zeros(3), quat)
    step_times = {name: np.empty(repeats) for name in controllers}
    net_times = {name: np.empty(repeats) for name in controllers}
    for i in range(repeats):
        for name, ctrl in controllers.items():
            t0 = time.perf_counter()
            ctrl.step(i * 0.02, np.array([0.1, 0, 0]), home, np.zeros(30), np.zeros(3), quat)
            t1 = time.perf_counter()
            ctrl.policy.action(x[i])
            net_times[name][i], step_times[name][i] = time.perf_counter() - t1, t1 - t0
    print(f"inference, policy {sizes} ({n_in} inputs = {obs.history} frames), one thread, {repeats} steps "
          f"(load average {os.getloadavg()[0]:.1f}); {onnx_note}")
    for name in controllers:
        st, nt = step_times[name], net_times[name]
        print(f"  {name:12s} 50 Hz step (reference interpolation included): median {np.median(st) * 1e3:.3f} ms, "
              f"p99 {np.percentile(st, 99) * 1e3:.3f} ms; network alone: median {np.median(nt) * 1e3:.3f} ms, "
              f"p99 {np.percentile(nt, 99) * 1e3:.3f} ms")


def bench_env(mjx_batches: tuple[int, ...], cpu_batches: tuple[int, ...], steps: int) -> None:
    """Env steps/s of the jitted, vmapped environment step (compilation excluded) for each physics backend, in one
    run so the ratio is measured under the same load: MJX (JAX on this machine's CPU) and classic MuJoCo on
    threads. Default env (residual walking reference, domain randomisation, pushes), zero actions."""
    import jax
    import jax.numpy as jnp

    from toddlerbot.rl.config import EnvConfig
    from toddlerbot.rl.reference import load_reference
    from toddlerbot.rl.walk_env import WalkEnv
    from toddlerbot.robot.description import RobotDescription

    description = RobotDescription.load()
    t0 = time.perf_counter()
    reference, _ = load_reference(description, EnvConfig().command, EnvConfig().ctrl_dt)
    print(f"ZMP reference table: {time.perf_counter() - t0:.1f} s", flush=True)
    rates = {}
    for backend, batches in (("mjx", mjx_batches), ("cpu", cpu_batches)):
        env = WalkEnv(replace(EnvConfig(), backend=backend), description, reference=reference)
        for batch in batches:
            reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
            t0 = time.perf_counter()
            state = reset(jax.random.split(jax.random.PRNGKey(0), batch))
            jax.block_until_ready(state.obs)
            t_reset = time.perf_counter() - t0
            action = jnp.zeros((batch, env.action_size))
            t0 = time.perf_counter()
            state = step(state, action)
            jax.block_until_ready(state.obs)
            t_step = time.perf_counter() - t0
            t0 = time.perf_counter()
            for _ in range(steps):
                state = step(state, action)
            jax.block_until_ready(state.obs)
            rate = batch * steps / (time.perf_counter() - t0)
            rates[backend] = max(rates.get(backend, 0.0), rate)
            print(f"{backend} batch {batch:4d}: compile reset {t_reset:.1f} s, step {t_step:.1f} s; {rate:.0f} env "
                  f"steps/s ({rate * env.cfg.n_substeps:.0f} physics steps/s, {rate * env.cfg.ctrl_dt:.2f}x real "
                  f"time); load average {os.getloadavg()[0]:.1f}", flush=True)
    if "mjx" in rates and "cpu" in rates:
        print(f"CPU backend / MJX (best batch of each, this run): {rates['cpu'] / rates['mjx']:.2f}x")


def bench_ppo_epochs(backend: str, epochs: int, smoke: bool, compile_cache: bool) -> None:
    """``epochs`` PPO epochs of the walk environment's recipe on ``backend`` (the smoke run's, with its XLA flags,
    or the full one): per epoch the seconds JAX spent compiling and the seconds of training apart, so that a second
    compilation shows. With ``compile_cache`` the persistent cache is used (run twice: cold, then warm)."""
    import jax

    from toddlerbot.rl import train
    from toddlerbot.rl.compilation import compile_clock, use_compile_cache
    from toddlerbot.rl.environments import environment_class

    print(use_compile_cache(compile_cache).describe())
    clock = compile_clock()
    env_class = environment_class("walk")
    env_cfg = env_class.default_config(smoke)
    t0 = time.perf_counter()
    env = env_class(replace(env_cfg, backend=backend))
    recipe = env_class.recipe(backend, smoke)
    ppo = train.PPO(env, recipe.ppo)
    print(f"{backend} backend, {'smoke' if smoke else 'full'} recipe: {recipe.ppo.num_envs} envs, "
          f"{ppo.updates_per_epoch * recipe.ppo.env_steps_per_update} env steps per epoch; environment built in "
          f"{time.perf_counter() - t0:.1f} s", flush=True)
    compiled, t0 = clock.seconds(), time.perf_counter()
    ts = ppo.initial_state(jax.random.PRNGKey(0))
    env_state = jax.block_until_ready(ppo.reset(jax.random.PRNGKey(1)))
    print(f"initial state and reset: compile {clock.seconds() - compiled:.1f} s, "
          f"total {time.perf_counter() - t0:.1f} s", flush=True)
    for i in range(epochs):
        compiled, t0 = clock.seconds(), time.perf_counter()
        ts, env_state, _ = ppo.epoch(ts, env_state, jax.random.PRNGKey(10 + i))
        wall, compiling = time.perf_counter() - t0, clock.seconds() - compiled
        steps = ppo.updates_per_epoch * recipe.ppo.env_steps_per_update
        print(f"epoch {i + 1}: compile {compiling:.1f} s, training {wall - compiling:.2f} s "
              f"({steps / (wall - compiling):.0f} env steps/s); load average {os.getloadavg()[0]:.1f}", flush=True)


HELD_OUT_SCHEDULES = {
    "fwd-back": "0:0.12,0,0; 4:0.15,0,0; 9:0,0,0; 11:-0.08,0,0; 16:0,0,0",
    "side-turn": "0:0,0,0; 1:0,0.06,0; 5:0,-0.06,0; 9:0,0,0.35; 13:0,0,-0.35; 17:0.08,0.03,0.2; 21:0,0,0",
}
"""Schedules no training run saw (commands are drawn at random in training): 0.15 m/s forward, -0.08 m/s backward,
+-0.06 m/s sideways, +-0.35 rad/s turns and a curve."""


def bench_tracking(policies: list[str], weights: str | None, plot_dir: str | None, asymmetric: bool = False) -> None:
    """Table 7 errors of each policy (``walk-rl`` with ``weights``) on the default and the held-out schedules in the
    CPU simulator (1 ms physics, actuator model), against 1.5 x the appendix's simulation errors."""
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, TRACKING_BARS, evaluate_policy, plot_velocity_tracking

    description = RobotDescription.load()
    print(f"tracking errors (position m, lin vel m/s, ang vel rad/s); bars 1.5 x Table 7: {TRACKING_BARS}")
    for name in policies:
        for label, schedule in {"default": DEFAULT_COMMANDS, **HELD_OUT_SCHEDULES}.items():
            seconds = float(schedule.split(";")[-1].split(":")[0]) + 2.0 if label != "default" else 26.0
            t0 = time.perf_counter()
            r = evaluate_policy(description, name, schedule, seconds, weights=weights if name == "walk-rl" else None,
                                symmetric=not asymmetric)  # an option only walk-rl takes (make_policy)
            errors = (r.position_m, r.lin_vel_mps, r.ang_vel_radps)
            ok = r.falls == 0 and all(e <= b for e, b in zip(errors, TRACKING_BARS, strict=True))
            wall = time.perf_counter() - t0
            print(f"  {name:8s} {label:9s}: {r.position_m:.3f} m, {r.lin_vel_mps:.3f} m/s, "
                  f"{r.ang_vel_radps:.3f} rad/s, falls {r.falls} ({r.duration_s:.0f} s simulated, {wall:.0f} s wall) "
                  f"{'meets' if ok else 'MISSES'} the bars", flush=True)
            if plot_dir:
                plot_velocity_tracking(r, f"{name}, {label}", Path(plot_dir) / f"tracking_{name}_{label}.png")


def curves(runs: list[str], path: str) -> None:
    """Learning curves of training runs (``label=run_dir``) in one figure, and each run's key numbers."""
    from toddlerbot.rl.plot import learning_curves, run_records
    from toddlerbot.rl.walk_env import WalkEnv

    records = {}
    for item in runs:
        label, _, run_dir = item.partition("=")
        warm, history = run_records(Path(run_dir))
        records[label] = (warm, history)
        for name, rows in (("warm start", warm), ("PPO", history)):
            if rows:
                last = rows[-1]
                print(f"{label} {name}: {len(rows)} records, {last['env_steps']:,} env steps, "
                      f"{last['walltime'] / 60:.1f} min; " + ", ".join(
                          f"{k} {last[k]:.4g}" for k in ("bc_loss", "fall_rate", "episode_reward", "episode_length",
                                                         "lin_vel_error", "ang_vel_error", "sps") if k in last))
    print(f"curves: {learning_curves(records, Path(path), WalkEnv.curves)}")


SETTINGS = (  # (contacts, Newton iterations, line-search iterations, Jacobian, linkage weld loops)
    ("all", 4, 8, "dense", True),  # round 1's model
    ("all", 4, 8, "dense", False),
    ("feet_hands", 4, 8, "dense", False),  # the default
    ("feet_hands", 3, 6, "dense", False),
    ("feet_hands", 2, 4, "dense", False),
    ("feet_hands", 1, 4, "dense", False),
    ("feet_hands", 4, 8, "sparse", False),
)


def _config(setting: tuple):
    from toddlerbot.rl.config import EnvConfig

    contacts, iterations, ls_iterations, jacobian, loops = setting
    return replace(EnvConfig(), randomize=False, contacts=contacts, solver_iterations=iterations,
                   solver_ls_iterations=ls_iterations, jacobian=jacobian, linkage_loops=loops, backend="mjx")


def _label(setting: tuple) -> str:
    contacts, iterations, ls_iterations, jacobian, loops = setting
    return f"{contacts:10s} Newton {iterations}/{ls_iterations} {jacobian:6s} {'loops' if loops else 'coupled'}"


def bench_solver_cpu(seconds: float, settings: tuple = SETTINGS) -> None:
    """Each setting's training model stepped by CPU MuJoCo (float64, no JAX): stable or not, torso height,
    constraint residual, physics steps/s."""
    from toddlerbot.rl.checks import equality_residual, stand_cpu
    from toddlerbot.rl.model import training_model
    from toddlerbot.robot.description import RobotDescription

    description = RobotDescription.load()
    print(f"CPU MuJoCo (float64), home pose held for {seconds:.0f} s:")
    for setting in settings:
        model = training_model(description, _config(setting))
        t0 = time.perf_counter()
        diverged, z, qpos = stand_cpu(model, description, seconds)
        rate = len(z) / (time.perf_counter() - t0)
        if diverged is not None:
            print(f"  {_label(setting)}: diverged at {diverged:.3f} s")
            continue
        residual, worst = equality_residual(model, qpos)
        print(f"  {_label(setting)}: torso {z[0]:.4f} -> {z[-1]:.4f} m; equality residual {residual:.1e} "
              f"({worst}); {rate:.0f} physics steps/s", flush=True)


def bench_settings(n_envs: int, seconds: float, settings: tuple = SETTINGS) -> None:
    """For each training-model setting in MJX: zero-action standing without randomisation (falls, torso
    height), the transmission constraints' worst residual, and env steps/s of the compiled rollout."""
    from toddlerbot.rl.checks import equality_residual, stand
    from toddlerbot.rl.config import smoke_env_config
    from toddlerbot.rl.reference import standing_table
    from toddlerbot.rl.walk_env import WalkEnv
    from toddlerbot.robot.description import RobotDescription

    description = RobotDescription.load()
    reference = standing_table(description, smoke_env_config().command, period=0.6)
    gains = (np.ones(description.n_motors), np.zeros((2, description.n_motors)))
    print(f"MJX stand {seconds:.0f} s with zero actions, {n_envs} envs, no randomisation, "
          f"matmul precision {_precision()}:")
    for setting in settings:
        env = WalkEnv(_config(setting), description, reference=reference, gain_scales=gains)
        r = stand(env, n_envs, seconds)
        z = r.torso_height
        residual, worst = equality_residual(env.mj_model, r.qpos)
        print(f"  {_label(setting)}: {int(r.fallen.sum())}/{n_envs} fell; torso {z[0].mean():.4f} -> "
              f"{z[-1].mean():.4f} m (min {z.min():.4f}); equality residual {residual:.2e} ({worst}); "
              f"{z.size / r.run_s:.0f} env steps/s (compile {r.compile_s:.0f} s)", flush=True)


def _precision() -> str:
    import jax

    return str(jax.config.jax_default_matmul_precision)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--env", action="store_true",
                        help="also benchmark the environment on both physics backends (minutes on a CPU)")
    parser.add_argument("--mjx-batches", type=int, nargs="+", default=[32, 128])
    parser.add_argument("--cpu-batches", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--solver-cpu", action="store_true",
                        help="each setting's model in CPU MuJoCo (float64): stable?, residual (seconds, no JAX)")
    parser.add_argument("--settings", type=int, nargs="*", default=None, metavar="INDEX",
                        help="stand check, constraint residuals and env steps/s for each training-model setting "
                             "(or only those at these indices of SETTINGS, in this order)")
    parser.add_argument("--tracking", nargs="*", default=None, metavar="POLICY",
                        help="Table 7 errors on the default and held-out schedules (default policies: walk-rl)")
    parser.add_argument("--weights", default=None, help="walk-rl's exported .npz (default: the shipped one)")
    parser.add_argument("--plots", default=None, help="folder for the tracking plots")
    parser.add_argument("--asymmetric", action="store_true",
                        help="walk-rl without its mirror image (docs/rl.md \"Mirror symmetry\")")
    parser.add_argument("--curves", nargs="+", default=None, metavar="LABEL=RUN",
                        help="plot the learning curves of these training runs (only)")
    parser.add_argument("--out", default="docs/figures/rl_learning_curves.png", help="figure of --curves")
    parser.add_argument("--ppo-epochs", type=int, default=0, metavar="N",
                        help="run N PPO epochs of the walk recipe: compile and training time per epoch (only)")
    parser.add_argument("--backend", choices=("mjx", "cpu"), default="mjx", help="physics of --ppo-epochs")
    parser.add_argument("--smoke", action="store_true", help="--ppo-epochs of the smoke recipe (its XLA flags)")
    parser.add_argument("--compile-cache", action="store_true",
                        help="--ppo-epochs with the persistent compilation cache (default: off, a cold compile)")
    parser.add_argument("--stand-envs", type=int, default=8)
    parser.add_argument("--stand-seconds", type=float, default=10.0)
    args = parser.parse_args()
    if args.smoke:
        from toddlerbot.rl.config import SMOKE_XLA_FLAGS

        os.environ.setdefault("XLA_FLAGS", SMOKE_XLA_FLAGS)  # before JAX starts, as `rl train --smoke` does
    if args.env or args.settings is not None or args.ppo_epochs:
        from toddlerbot.rl.precision import use_full_precision

        use_full_precision()  # as training does, before anything compiles
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, {platform.processor() or 'cpu'}")
    if args.curves:
        curves(args.curves, args.out)
        return
    if args.ppo_epochs:
        bench_ppo_epochs(args.backend, args.ppo_epochs, args.smoke, args.compile_cache)
        return
    if args.tracking is not None:
        bench_tracking(args.tracking or ["walk-rl"], args.weights, args.plots, args.asymmetric)
        return
    bench_inference()
    if args.env:
        bench_env(tuple(args.mjx_batches), tuple(args.cpu_batches), args.steps)
    if args.solver_cpu:
        bench_solver_cpu(args.stand_seconds)
    if args.settings is not None:
        chosen = tuple(SETTINGS[i] for i in args.settings) if args.settings else SETTINGS
        bench_settings(args.stand_envs, args.stand_seconds, chosen)


if __name__ == "__main__":
    main()
