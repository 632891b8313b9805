"""``toddlerbot rl``: train a walking policy with PPO in MJX and export it for numpy or onnxruntime inference."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Annotated, Literal

import typer

from toddlerbot.cli.options import (
    MotorParamsOption,
    TensorBoardOption,
    WandbModeOption,
    WandbOption,
    dashboards,
    seed_option,
    training_budget,
)
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir, output_file, source_checkout
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.motions import builtin_motions
from toddlerbot.rl.config import PHYSICS_BACKENDS, RandomizationConfig
from toddlerbot.rl.distributed import Processes
from toddlerbot.rl.environments import ENVIRONMENTS
from toddlerbot.rl.launch import TrainRequest
from toddlerbot.rl.onnx_export import EXPORT_FORMATS
from toddlerbot.sim.terrain import MIN_START, START

app = typer.Typer(help="Reinforcement-learning locomotion (needs the \\[train] extra: jax, mujoco-mjx, brax).",
                  no_args_is_help=True)


def _require_jax() -> None:
    try:
        import brax  # noqa: F401
        import jax  # noqa: F401
        from mujoco import mjx  # noqa: F401
    except ImportError as exc:
        raise ToddlerbotError(f"RL training needs the [train] extra (pip install 'toddlerbot[train]'): {exc}") from exc


OutOption = Annotated[Path | None, typer.Option(help="Run directory (default runs/rl/<timestamp>).")]
SmokeOption = Annotated[bool, typer.Option(help="Tiny configuration that finishes on a 2-core CPU in minutes.")]
ResumeOption = Annotated[Path | None, typer.Option(help="Continue the run in this directory from its last "
                                                        "checkpoint.")]
TimestepsOption = Annotated[int | None, typer.Option(
    help="Override the number of environment steps (with --resume: the run's new budget).")]
NumEnvsOption = Annotated[int | None, typer.Option(help="Override the number of parallel environments.")]
MinutesOption = Annotated[float | None, typer.Option(help="Stop after the epoch that passes this wall time (resume "
                                                          "later with --resume).")]
EpochsOption = Annotated[int | None, typer.Option(help="Stop after this many epochs (resume later with --resume).")]
SolverIterationsOption = Annotated[int | None, typer.Option(help="Newton iterations of the training model (default "
                                                                 "4; see docs/rl.md before lowering).")]
LsIterationsOption = Annotated[int | None, typer.Option(help="Line-search iterations (default 8).")]
EnvOption = Annotated[str | None, typer.Option(
    "--env", help=f"Registered environment to train: {', '.join(ENVIRONMENTS.names())} (default walk; docs/rl.md "
                  "\"Environments\"; installed packages add more).")]
MotionOption = Annotated[str | None, typer.Option(
    help=f"The motion --env track tracks: a built-in ({', '.join(builtin_motions())}) or a motion file (required "
         "there; docs/rl.md \"Motion tracking\").")]
BackendOption = Annotated[Literal[("auto", *PHYSICS_BACKENDS)], typer.Option(  # the backends rl.config knows
    help="Physics: cpu (classic MuJoCo on threads), mjx, or auto (mjx with a GPU, else cpu: then the CPU recipe of "
         "docs/rl.md).")]
ImitationIterationsOption = Annotated[int | None, typer.Option(help="DAgger iterations of the warm start from "
                                                                    "walk-zmp (0: none; default: the recipe's).")]
VariantOption = Annotated[str | None, typer.Option(help="Spec variant to train (e.g. gripper: 32 motors); "
                                                        "exported as walk_rl_<variant>.npz.")]
UpperBodyPoseOption = Annotated[float | None, typer.Option(
    help="Randomise the arms, grippers and neck: each target drawn with every command between home and this "
         "fraction of the way to its limits (default 0: held at home).")]
HandForceOption = Annotated[float | None, typer.Option(
    help="Pull the hands (a wagon's handle, a carried load): with every command a force of up to this many "
         "newtons in a random horizontal direction, and up to half of it up or down (default 0: none).")]
PushVelocityOption = Annotated[tuple[float, float] | None, typer.Option(
    help="Pushes in training: each kick's speed uniform between these two m/s (default: from 0 to the recipe's "
         "largest push); a band near the largest trains recovery from the kicks of the robustness benchmark. "
         "With --resume: the run goes on with this band from its last checkpoint (a curriculum in stages).")]
PushIntervalOption = Annotated[tuple[float, float] | None, typer.Option(
    help="Pushes in training: seconds from one push to the next, uniform between these two (default: "
         "{:g}-{:g} s); shorter trains recovery from kicks in quick succession. With --resume: the run goes on "
         "with these intervals from its last checkpoint (a stage, as with --push-velocity).".format(
             *RandomizationConfig().push_interval_s))]
ImuAgeOption = Annotated[tuple[float, float] | None, typer.Option(
    help="The IMU reading the policy sees is this many seconds old, uniform between these two per episode, at most "
         "one control period (default 0 0: fresh); a real BNO08x's are 5-15 ms old. With --resume: the run goes "
         "on with these ages from its last checkpoint (a stage, as with --push-velocity).")]
TerrainOption = Annotated[str | None, typer.Option(
    help="The ground every environment walks on: NAME[:KEY=VALUE,...] (docs/simulation.md \"Terrain\"; e.g. "
         "mix:height=0.02,degrees=10). Default: the flat floor. With --resume: the run goes on on this ground from "
         "its last checkpoint (a terrain curriculum in stages).")]
TerrainSeedOption = Annotated[int | None, typer.Option(
    help="The seed the --terrain is drawn from (default 0; with --resume: a next stage on a new draw).")]
InitPolicyOption = Annotated[Path | None, typer.Option(
    help="Continue an exported walk policy (an .npz, or a shipped one by name: walk_rl): its actor and settings, "
         "a critic fitted to its returns first (docs/rl.md \"Walking on terrain\").")]
MirrorLossOption = Annotated[float | None, typer.Option(
    help="Weight of a mirror-symmetry loss in PPO: the policy is trained to act as its own left-right mirror "
         "image (default 0: off; docs/rl.md \"Mirror symmetry\").")]
TerrainStartOption = Annotated[float | None, typer.Option(
    help=f"Half-width of the flat square the training envs start on, m (default {START:g}, the simulator's; at least "
         f"{MIN_START:g}; with --resume a next stage): smaller, every episode walks onto the --terrain at once.")]
DesiredKlOption = Annotated[float | None, typer.Option(
    help="The KL per minibatch PPO's adaptive step size aims at (default 0.01; with --resume a next stage; a "
         "continued policy may need a looser target, docs/rl.md \"Walking on terrain\").")]
RewardWeightOption = Annotated[list[str] | None, typer.Option(
    help="Override a reward term's weight, NAME=WEIGHT (repeatable; e.g. path_xy=5 for the position-tracking term "
         "that is off by default: docs/rl.md \"Rewards\").")]
CompileCacheOption = Annotated[bool, typer.Option(
    "--compile-cache/--no-compile-cache",
    help="Keep compiled programs in JAX's persistent compilation cache (~/.cache/toddlerbot/jax, or the folder "
         "TODDLERBOT_COMPILE_CACHE names; TODDLERBOT_COMPILE_CACHE=off also turns it off), so that a second run or a "
         "resume of the same configuration loads them instead of compiling (docs/rl.md).")]
CoordinatorOption = Annotated[str | None, typer.Option(
    help="Train over several processes or machines (jax.distributed): HOST:PORT of process 0's coordinator, the "
         "same for every process, with --num-processes and --process-id (under SLURM's srun or Open MPI's mpirun JAX "
         "reads all three from the environment); docs/rl.md \"Training on several GPUs or machines\".")]
NumProcessesOption = Annotated[int | None, typer.Option(
    help="How many processes train together (--coordinator; 1: this one alone).")]
ProcessIdOption = Annotated[int | None, typer.Option(
    help="This process's number, 0 to --num-processes - 1; process 0 alone writes the run directory.")]
WarmStartOption = Annotated[Path | None, typer.Option(
    help="Start PPO from this run's DAgger warm start (with its environment, networks and exploration noise) "
         "instead of making one: the teacher runs on CPU cores, so make it once and train on a GPU from it.")]


@app.command()
def train(
    out: OutOption = None,
    env: EnvOption = None,
    motion: MotionOption = None,
    smoke: SmokeOption = False,
    resume: ResumeOption = None,
    timesteps: TimestepsOption = None,
    num_envs: NumEnvsOption = None,
    seed: Annotated[int, seed_option("PRNG seed.")] = 0,
    minutes: MinutesOption = None, epochs: EpochsOption = None,
    solver_iterations: SolverIterationsOption = None, ls_iterations: LsIterationsOption = None,
    backend: BackendOption = "auto",
    imitation_iterations: ImitationIterationsOption = None,
    motor_params: MotorParamsOption = None,
    warm_start: WarmStartOption = None, init_policy: InitPolicyOption = None,
    terrain: TerrainOption = None, terrain_seed: TerrainSeedOption = None, terrain_start: TerrainStartOption = None,
    variant: VariantOption = None,
    upper_body_pose: UpperBodyPoseOption = None,
    hand_force: HandForceOption = None,
    push_velocity: PushVelocityOption = None, push_interval: PushIntervalOption = None, imu_age: ImuAgeOption = None,
    mirror_loss: MirrorLossOption = None, desired_kl: DesiredKlOption = None,
    reward_weight: RewardWeightOption = None,
    tensorboard: TensorBoardOption = True, wandb: WandbOption = False, wandb_mode: WandbModeOption = None,
    compile_cache: CompileCacheOption = True,
    coordinator: CoordinatorOption = None, num_processes: NumProcessesOption = None, process_id: ProcessIdOption = None,
) -> None:
    """Train an environment (--env, default walk) with PPO on its recipe: checkpoints, curve, TensorBoard, W&B."""
    for limit, count, option in ((minutes, epochs, "--epochs"), (None, timesteps, "--timesteps"),
                                 (None, num_envs, "--num-envs")):
        training_budget(limit, count, option)
    sinks = dashboards(tensorboard, wandb, wandb_mode)  # a missing package fails here, before anything compiles
    processes = Processes(coordinator, num_processes, process_id)  # checked before anything starts
    request = TrainRequest(smoke, timesteps, num_envs, seed, solver_iterations, ls_iterations, backend,
                           imitation_iterations, tuple(motor_params or ()), warm_start, variant, upper_body_pose,
                           hand_force, push_velocity, push_interval, imu_age, mirror_loss, tuple(reward_weight or ()),
                           env, motion, terrain, terrain_seed, init_policy, desired_kl, terrain_start)
    plan = _plan(out, resume, request, compile_cache, processes)
    _report(plan.run_dir, _train_with_progress(plan, minutes, epochs, sinks))


def _report(run_dir: Path, history: list[dict]) -> None:
    """The run's training curve and closing line (process 0's; the others' closing line only)."""
    if not history:
        raise ToddlerbotError(f"{run_dir}: no epoch ran (limits too tight?)")
    from toddlerbot.rl.distributed import is_main

    if not is_main():
        console.print(f"done: {history[-1]['env_steps']:,} env steps; process 0 wrote {run_dir}")
        return
    from toddlerbot.rl.environments import environment_class
    from toddlerbot.rl.plot import write_run_curve
    from toddlerbot.rl.train import load_config

    png = write_run_curve(run_dir, history, environment_class(load_config(run_dir)[0].environment).curves)
    last = history[-1]
    compiling = sum(record.get("compile_s", 0.0) for record in history)  # runs before issue 45 recorded none
    console.print(f"done: {last['env_steps']:,} env steps in {last['walltime']:.0f} s ({compiling:.0f} s of it "
                  f"compiling PPO, then {last['sps']:.0f} steps/s), reward/step {last['step_reward']:.3f}; "
                  f"curve {png}")


def _plan(out: Path | None, resume: Path | None, request: TrainRequest, compile_cache: bool = True,
          processes: Processes | None = None):
    """The training plan, JAX started with the smoke run's XLA flags where the run is (or resumes) a smoke run, and
    with its persistent compilation cache on or off; joined to the run's other processes where it has several (their
    plans write nothing: process 0's does)."""
    import os

    from toddlerbot.rl.config import SMOKE_XLA_FLAGS
    from toddlerbot.rl.launch import is_smoke_run, new_run_plan, resume_plan

    processes = processes or Processes()
    if processes.wanted() and out is None and resume is None:
        raise ToddlerbotError("--out: a run of several processes needs its run directory named (the same folder for "
                              "every process)")
    if request.smoke or (resume is not None and is_smoke_run(resume)):  # before JAX starts its CPU backend
        os.environ.setdefault("XLA_FLAGS", SMOKE_XLA_FLAGS)
    _require_jax()
    from toddlerbot.rl.distributed import is_main, join

    joined = join(processes)  # before anything touches JAX's devices
    if joined:
        console.print(joined)
    write = is_main()
    from toddlerbot.rl.compilation import use_compile_cache

    console.print(use_compile_cache(compile_cache).describe())  # before anything compiles
    if resume is not None:
        return resume_plan(resume, request, write)
    if request.imitation_iterations:
        training_budget(None, request.imitation_iterations, "--imitation-iterations")
    run_dir = out or Path("runs/rl") / datetime.now().strftime("%Y%m%d-%H%M%S")
    if write:
        run_dir = output_dir(run_dir, "--out", default=out is None)  # the default's folder is made
    return new_run_plan(run_dir, request, write)


def _train_with_progress(plan, minutes: float | None, epochs: int | None, sinks) -> list[dict]:
    """`rl.train.train` with a progress bar of the DAgger warm start, then of PPO."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from toddlerbot.rl.distributed import is_main
    from toddlerbot.rl.train import train as run_training

    console.print(f"run directory: {plan.run_dir}")

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                  TimeElapsedColumn(), console=console, disable=not is_main()) as bar:  # process 0's bar alone
        task = bar.add_task("compiling + training", total=None, info="")

        def progress(done: int, total: int, m: dict) -> None:
            bar.update(task, completed=done, total=total, description="training",
                       info=f"{done:,} steps  reward/step {m['step_reward']:.3f}  episode {m['episode_length']:.0f}"
                            f"  KL {m['kl_mean']:.3f}  {m['sps']:.0f} steps/s")

        def imitation_progress(m: dict) -> None:
            dagger = "bc_loss" in m  # else the critic of --init-policy's actor (`toddlerbot.rl.policy_start`)
            fit = f"BC loss {m['bc_loss']:.4f}" if dagger else f"value loss {m['value_loss']:.4f}"
            bar.update(task, description="DAgger from walk-zmp" if dagger else "critic of the initial policy",
                       info=f"iteration {m['iteration']}: {m['samples']:,} samples, {fit}, "
                            f"falls/step {m['fall_rate']:.4f}")

        _, history = run_training(plan.run_dir, plan.env, plan.ppo, resume=plan.resume, progress=progress,
                                  time_limit_s=None if minutes is None else 60 * minutes, max_epochs=epochs,
                                  imitation_cfg=plan.imitation, imitation_progress=imitation_progress,
                                  dashboards=sinks)
    return history


SelectOption = Annotated[int | None, typer.Option(
    help="Export the best of the run's last N checkpoints instead of the latest: each walks the policy's reach in the "
         "simulator under --select-kick kicks and on each --select-terrain, on seeds no benchmark uses; fewest "
         "falls, then least stray, wins (docs/rl.md \"Checkpoint selection\").")]
SelectKickOption = Annotated[float, typer.Option(help="With --select: m/s of the kicks on the flat floor.")]
SelectSeedsOption = Annotated[int | None, typer.Option(
    min=1, help="With --select: seeds per trial (default: those of toddlerbot.rl.selection.SELECTION_SEEDS).")]
SelectTerrainOption = Annotated[list[str] | None, typer.Option(
    help="With --select: also walk on this ground without kicks (repeatable; e.g. rough:height=0.02).")]


@app.command()
def export(
    run: Annotated[Path, typer.Argument(help="Training run directory, or an exported .npz (for --format onnx).")],
    out: Annotated[Path | None, typer.Option(help="File to write (default: RUN/policy.npz, or for onnx the "
                                                  "source's name with .onnx, or RUN/policy.onnx).")] = None,
    export_format: Annotated[Literal[EXPORT_FORMATS], typer.Option(
        "--format", help="npz (numpy inference) or onnx (onnxruntime; checked against the numpy policy).")] = "npz",
    checkpoint: Annotated[str | None, typer.Option(help="A checkpoint file name of the run (default: the latest; "
                                                        "'warm_start': the DAgger warm start).")] = None,
    select: SelectOption = None, select_kick: SelectKickOption = 0.3, select_seeds: SelectSeedsOption = None,
    select_terrain: SelectTerrainOption = None,
    ship: Annotated[bool, typer.Option(help="Maintainers, in a source checkout: write the package's shipped policy "
                                            "(walk_rl.npz, or walk_rl_<variant>.npz for a variant's run) that every "
                                            "walk-rl run loads by default (docs/rl.md, \"Shipping a policy\").")]
    = False,
) -> None:
    """Write the run's latest checkpoint as a policy file for the `walk-rl` runtime policy: numpy-only .npz, or
    .onnx (graph: raw observation -> action; metadata in the model) verified against the numpy policy."""
    out = _export_target(run, out, export_format, ship)
    if export_format == "onnx":
        from toddlerbot.rl.onnx_export import export_onnx, require_onnx

        require_onnx()
        if run.is_dir():
            _require_jax()
        path, report = export_onnx(run, out, checkpoint=checkpoint)
        console.print(f"exported {path} ({path.stat().st_size / 1024:.0f} KiB); ONNX vs numpy, max abs action "
                      f"difference: {report['random']:.2g} on {report['n_random']} random observations, "
                      f"{report['recorded']:.2g} on {report['n_recorded']} recorded in the simulator", soft_wrap=True)
        return
    _require_jax()
    from toddlerbot.rl.export import export_run

    selection = None
    if select is not None:
        checkpoint, selection = _select(run, checkpoint, select, select_kick, tuple(select_terrain or ()),
                                        select_seeds)
    path = export_run(run, out, checkpoint=checkpoint, extra_meta=selection and {"selection": selection})
    console.print(f"exported {path} ({path.stat().st_size / 1024:.0f} KiB)")


def _select(run: Path, checkpoint: str | None, last: int, kick: float, terrains: tuple[str, ...],
            seeds: int | None) -> tuple[str, dict]:
    """The selected checkpoint and the record of the selection (trials, every candidate's row) for the export."""
    from dataclasses import asdict

    if checkpoint is not None:
        raise ToddlerbotError("--select chooses the checkpoint; drop --checkpoint")
    from toddlerbot.rl.selection import SELECTION_SEEDS, SelectionTrials, select_checkpoint

    first = SELECTION_SEEDS[0]
    trials = SelectionTrials(kick=kick, terrains=terrains,
                             seeds=SELECTION_SEEDS if seeds is None else tuple(range(first, first + seeds)))
    best, rows = select_checkpoint(run, last, trials, progress=lambda name, row: console.print(
        f"{name}: {row['falls']}/{row['trials']} falls, stray {row['stray_m']:.3f} m"))
    console.print(f"selected {best}")
    return best, {"trials": asdict(trials), "candidates": rows, "selected": best}


def _export_target(run: Path, out: Path | None, export_format: str, ship: bool) -> Path:
    """The file `rl export` writes, checked (never the run's own files; into the package only with --ship, from a
    source checkout): by default beside the run (RUN/policy.npz), or the .npz's name with .onnx."""
    from toddlerbot.rl.run_files import run_inputs

    inputs = run_inputs(run) if run.is_dir() else [run]
    if export_format == "onnx":
        if ship:
            raise ToddlerbotError("--ship writes the shipped .npz policy; drop --format onnx")
        return output_file(out or (run / "policy.onnx" if run.is_dir() else run.with_suffix(".onnx")), "--out",
                           inputs)
    if not run.is_dir():
        raise ToddlerbotError(f"{run}: not a training run directory (an .npz is already the numpy export; "
                              "--format onnx converts it)")
    if ship:
        from toddlerbot.rl.environments import environment_class
        from toddlerbot.rl.train import load_config

        if out is not None:
            raise ToddlerbotError("--ship writes the package's shipped policy; drop --out")
        env_cfg = load_config(run)[0]
        out = environment_class(env_cfg.environment).shipped_export(env_cfg)
        source_checkout("--ship")
    return output_file(out or run / "policy.npz", "--out", inputs, into_package=ship)
