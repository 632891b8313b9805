"""``toddlerbot rl``: train a walking policy with PPO in MJX and export it for numpy or onnxruntime inference."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Annotated

import typer

from toddlerbot.cli.options import (
    TensorBoardOption,
    WandbModeOption,
    WandbOption,
    dashboards,
    output_dir,
    output_file,
    training_budget,
)
from toddlerbot.cli.output import console
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_text
from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS

app = typer.Typer(help="Reinforcement-learning locomotion (needs the \\[train] extra: jax, mujoco-mjx, brax).",
                  no_args_is_help=True)



def _require_jax() -> None:
    try:
        import brax  # noqa: F401
        import jax  # noqa: F401
        from mujoco import mjx  # noqa: F401
    except ImportError as exc:
        raise ToddlerbotError(f"RL training needs the [train] extra (pip install 'toddlerbot[train]'): {exc}") from exc


@app.command()
def train(
    out: Annotated[Path | None, typer.Option(help="Run directory (default runs/rl/<timestamp>).")] = None,
    smoke: Annotated[bool, typer.Option(help="Tiny configuration that finishes on a 2-core CPU in minutes.")] = False,
    resume: Annotated[Path | None, typer.Option(help="Continue the run in this directory from its last checkpoint.")]
    = None,
    timesteps: Annotated[int | None, typer.Option(help="Override the number of environment steps.")] = None,
    num_envs: Annotated[int | None, typer.Option(help="Override the number of parallel environments.")] = None,
    seed: Annotated[int, typer.Option(help="PRNG seed.")] = 0,
    minutes: Annotated[float | None, typer.Option(help="Stop after the epoch that passes this wall time (resume "
                                                       "later with --resume).")] = None,
    epochs: Annotated[int | None, typer.Option(help="Stop after this many epochs (resume later with --resume).")]
    = None,
    solver_iterations: Annotated[int | None, typer.Option(help="Newton iterations of the training model "
                                                               "(default 4; see docs/rl.md before lowering).")]
    = None,
    ls_iterations: Annotated[int | None, typer.Option(help="Line-search iterations (default 8).")] = None,
    backend: Annotated[str, typer.Option(help="Physics: cpu (classic MuJoCo on threads), mjx, or auto (mjx with a "
                                               "GPU, else cpu: then the CPU recipe of docs/rl.md).")] = "auto",
    imitation_iterations: Annotated[int | None, typer.Option(help="DAgger iterations of the warm start from "
                                                                  "walk-zmp (0: none; default: the recipe's).")]
    = None,
    motor_params: Annotated[list[Path] | None, typer.Option(
        "--motor-params", help="Fitted actuator parameters (sysID params.json; repeat for several motor models): "
                               "the robot trains on them, domain randomisation scales around them.")] = None,
    warm_start: Annotated[Path | None, typer.Option(
        help="Start PPO from this run's DAgger warm start (with its environment, networks and exploration noise) "
             "instead of making one: the teacher runs on CPU cores, so make it once and train on a GPU from it.")]
    = None,
    tensorboard: TensorBoardOption = True,
    wandb: WandbOption = False,
    wandb_mode: WandbModeOption = None,
) -> None:
    """Train with PPO (on a CPU: the CPU recipe of docs/rl.md, a DAgger warm start from walk-zmp then PPO; with a
    GPU: the one-GPU configuration; --smoke: a tiny run) with checkpoints, a training curve and TensorBoard
    scalars (RUN/tensorboard; --wandb: also Weights & Biases)."""
    import os

    from toddlerbot.rl.config import SMOKE_XLA_FLAGS

    training_budget(minutes, epochs, "--epochs")
    for option, count in (("--timesteps", timesteps), ("--num-envs", num_envs)):
        training_budget(None, count, option)
    sinks = dashboards(tensorboard, wandb, wandb_mode)  # a missing package fails here, before anything compiles
    smoke_run = smoke or (resume is not None and (resume / "smoke").is_file())
    if smoke_run:  # must be set before JAX starts its CPU backend
        os.environ.setdefault("XLA_FLAGS", SMOKE_XLA_FLAGS)
    _require_jax()
    from dataclasses import replace

    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from toddlerbot.rl import config, plot
    from toddlerbot.rl import train as training

    if resume is not None:
        run_dir, env_cfg, ppo_cfg = resume, None, None
        if not (resume / "config.json").is_file():
            raise ToddlerbotError(f"{resume}: no training run to resume (config.json missing)")
        if motor_params or solver_iterations is not None or ls_iterations is not None or backend != "auto" \
                or imitation_iterations is not None or warm_start is not None:
            raise ToddlerbotError("--motor-params/--solver-iterations/--ls-iterations/--backend/"
                                  "--imitation-iterations/--warm-start: a resumed run keeps the settings it started "
                                  "with")
        imitation_cfg = None
    else:
        run_dir = output_dir(out or Path("runs/rl") / datetime.now().strftime("%Y%m%d-%H%M%S"), "--out")
        from toddlerbot.rl.env import resolve_backend

        if backend not in ("auto", *config.PHYSICS_BACKENDS):
            raise ToddlerbotError(f"--backend {backend!r}: expected auto, {', '.join(config.PHYSICS_BACKENDS)}")
        backend = resolve_backend(backend)
        source = None
        if warm_start is not None:
            if motor_params or imitation_iterations is not None:
                raise ToddlerbotError("--warm-start: the source run's warm start fixes its --motor-params and "
                                      "--imitation-iterations")
            source = training.warm_start_source(warm_start)
        env_cfg = source.env if source else config.smoke_env_config() if smoke else config.EnvConfig()
        try:
            env_cfg = replace(
                env_cfg, backend=backend,
                solver_iterations=env_cfg.solver_iterations if solver_iterations is None else solver_iterations,
                solver_ls_iterations=env_cfg.solver_ls_iterations if ls_iterations is None else ls_iterations)
        except ValueError as exc:
            raise ToddlerbotError(f"--solver-iterations/--ls-iterations: {exc}") from exc
        if motor_params:
            from toddlerbot.actuation.params_file import catalogue_with_params

            catalogue_with_params(motor_params)  # bad files fail here, before anything compiles
            env_cfg = replace(env_cfg, motor_params=tuple(str(p) for p in motor_params))
        cpu = backend == "cpu"
        ppo_cfg = replace(config.SMOKE if smoke else config.CPU if cpu else config.FULL, seed=seed)
        imitation_cfg = config.SMOKE_IMITATION if smoke else config.CPU_IMITATION if cpu else config.ImitationConfig()
        if source:
            ppo_cfg, imitation_cfg = source.policy_of(ppo_cfg), source.imitation
        if imitation_iterations is not None:
            training_budget(None, imitation_iterations or None, "--imitation-iterations")
            imitation_cfg = replace(imitation_cfg, iterations=imitation_iterations)
        try:
            if timesteps is not None:
                ppo_cfg = replace(ppo_cfg, num_timesteps=timesteps)
            if num_envs is not None:
                ppo_cfg = config.with_num_envs(ppo_cfg, num_envs)
        except ValueError as exc:
            raise ToddlerbotError(f"--num-envs/--timesteps: {exc}") from exc
        if source:
            training.adopt_warm_start(source.run_dir, run_dir)
    console.print(f"run directory: {run_dir}")
    if smoke and resume is None:
        run_dir.mkdir(parents=True, exist_ok=True)
        atomic_write_text(run_dir / "smoke", "this run uses the --smoke configuration\n")
    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                  TimeElapsedColumn(), console=console) as bar:
        task = bar.add_task("compiling + training", total=None, info="")

        def progress(done: int, total: int, m: dict) -> None:
            bar.update(task, completed=done, total=total, description="training",
                       info=f"{done:,} steps  reward/step {m['step_reward']:.3f}  episode {m['episode_length']:.0f}"
                            f"  KL {m['kl_mean']:.3f}  {m['sps']:.0f} steps/s")

        def imitation_progress(m: dict) -> None:
            bar.update(task, description="DAgger from walk-zmp",
                       info=f"iteration {m['iteration']}: {m['samples']:,} labels, BC loss {m['bc_loss']:.4f}, "
                            f"falls/step {m['fall_rate']:.4f}")

        _, history = training.train(run_dir, env_cfg, ppo_cfg, resume=resume is not None, progress=progress,
                                    time_limit_s=None if minutes is None else 60 * minutes, max_epochs=epochs,
                                    imitation_cfg=imitation_cfg, imitation_progress=imitation_progress,
                                    dashboards=sinks)
    if not history:
        raise ToddlerbotError(f"{run_dir}: no epoch ran (limits too tight?)")
    png = plot.training_curve(history, run_dir / "training_curve.png", warm=plot.run_records(run_dir)[0])
    last = history[-1]
    console.print(f"done: {last['env_steps']:,} env steps in {last['walltime']:.0f} s "
                  f"({last['sps']:.0f} steps/s), reward/step {last['step_reward']:.3f}; curve {png}")


@app.command()
def export(
    run: Annotated[Path, typer.Argument(help="Training run directory, or an exported .npz (for --format onnx).")],
    out: Annotated[Path | None, typer.Option(help="File to write (default: the shipped walk_rl.npz for npz; for "
                                                  "onnx the source's name with .onnx, or RUN/policy.onnx).")] = None,
    export_format: Annotated[str, typer.Option("--format", help="npz (numpy inference) or onnx (onnxruntime; "
                                                                 "checked against the numpy policy).")] = "npz",
    checkpoint: Annotated[str | None, typer.Option(help="A checkpoint file name of the run (default: the latest; "
                                                        "'warm_start': the DAgger warm start).")] = None,
) -> None:
    """Write the run's latest checkpoint as a policy file for the `walk-rl` runtime policy: numpy-only .npz, or
    .onnx (graph: raw observation -> action; metadata in the model) verified against the numpy policy."""
    from toddlerbot.rl.onnx_export import EXPORT_FORMATS

    if export_format not in EXPORT_FORMATS:
        raise ToddlerbotError(f"--format {export_format!r}: expected one of {', '.join(EXPORT_FORMATS)}")
    if export_format == "onnx":
        from toddlerbot.rl.onnx_export import export_onnx, require_onnx

        if out is None:
            out = run / "policy.onnx" if run.is_dir() else run.with_suffix(".onnx")
        output_file(out, "--out")
        require_onnx()
        if run.is_dir():
            _require_jax()
        path, report = export_onnx(run, out, checkpoint=checkpoint)
        console.print(f"exported {path} ({path.stat().st_size / 1024:.0f} KiB); ONNX vs numpy, max abs action "
                      f"difference: {report['random']:.2g} on {report['n_random']} random observations, "
                      f"{report['recorded']:.2g} on {report['n_recorded']} recorded in the simulator", soft_wrap=True)
        return
    if not run.is_dir():
        raise ToddlerbotError(f"{run}: not a training run directory (an .npz is already the numpy export; "
                              "--format onnx converts it)")
    out = DEFAULT_WEIGHTS if out is None else out
    output_file(out, "--out")
    _require_jax()
    from toddlerbot.rl.export import export_run

    path = export_run(run, out, checkpoint=checkpoint)
    console.print(f"exported {path} ({path.stat().st_size / 1024:.0f} KiB)")
