"""``toddlerbot dp``: train a diffusion policy on a demonstration dataset (needs the \\[dp] extra: torch)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated, Literal

import typer

from toddlerbot.cli.options import (
    TensorBoardOption,
    WandbModeOption,
    WandbOption,
    dashboards,
    duration,
    seed_option,
    training_budget,
)
from toddlerbot.cli.output import console
from toddlerbot.cli.output_paths import output_dir, output_file
from toddlerbot.dp import require_torch
from toddlerbot.dp.config import PRESETS
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import json_text

app = typer.Typer(help="Diffusion policy from demonstrations (needs the \\[dp] extra: torch==2.13.0).",
                  no_args_is_help=True)

MAX_EPISODE_SECONDS = 600.0
"""Longest simulated evaluation episode, s (a pick takes about 6 s)."""

DatasetArgument = Annotated[Path, typer.Argument(help="LeRobot v3.0 dataset directory (toddlerbot manip demo -o DIR) "
                                                      "or its decoded .npz (toddlerbot manip dataset decode).")]
RunOutOption = Annotated[Path, typer.Option("--out", "-o", help="Run directory (checkpoint.pt, loss_curve.png, ...).")]
MinutesOption = Annotated[float | None, typer.Option(help="Stop after this wall time (resume later with --resume).")]
StepsOption = Annotated[int | None, typer.Option(help="Stop at this total optimiser step count.")]
ResumeOption = Annotated[bool, typer.Option(help="Continue the run in --out from its checkpoint.")]
ConfigOption = Annotated[Literal[tuple(PRESETS)], typer.Option(help="Configuration preset.")]
ImagenetOption = Annotated[Path | None, typer.Option(help="Local torchvision ResNet-18 state dict (ImageNet) to start "
                                                          "the appendix config's encoder from.")]
CheckpointEveryOption = Annotated[int, typer.Option(min=1, help="Save checkpoint.pt every this many steps (and at "
                                                                "the end).")]
LogEveryOption = Annotated[int, typer.Option(min=1, help="Record the losses (metrics, TensorBoard, progress bar) every "
                                                         "this many steps (and at the end).")]
BinaryActionOption = Annotated[list[str] | None, typer.Option(
    "--binary-action", help="An action the demonstrations only open or close (a gripper motor, e.g. "
                            "left_gripper_drive; repeat for each): the policy commands one end of its demonstrated "
                            "range or the other, never a value between.")]
TrainSeedOption = Annotated[int | None, seed_option(help="Training seed of a new run (network, batches, noise, "
                                                        "validation episodes); default: the preset's (0).")]
BatchSizeOption = Annotated[int | None, typer.Option(min=1, help="Global batch of a new run (under torchrun: all "
                                                                 "processes together, split evenly); default: the "
                                                                 "preset's.")]


@app.command()
def train(
    dataset: DatasetArgument,
    out: RunOutOption,
    minutes: MinutesOption = None,
    steps: StepsOption = None,
    resume: ResumeOption = False,
    config: ConfigOption = "small",
    imagenet_weights: ImagenetOption = None,
    threads: Annotated[int, typer.Option(min=1, help="CPU threads for torch.")] = 2,
    device: Annotated[str, typer.Option(help="Torch device to train on: cpu, cuda, cuda:1, ...")] = "cpu",
    checkpoint_every: CheckpointEveryOption = 500,
    log_every: LogEveryOption = 50,
    batch_size: BatchSizeOption = None,
    binary_action: BinaryActionOption = None,
    seed: TrainSeedOption = None,
    tensorboard: TensorBoardOption = True,
    wandb: WandbOption = False,
    wandb_mode: WandbModeOption = None,
) -> None:
    """Train on the dataset's episodes (validation episodes held out), with a progress bar, a loss curve and
    TensorBoard scalars (OUT/tensorboard; --wandb: also Weights & Biases). Launched by torchrun with several
    processes it trains data-parallel (DistributedDataParallel: gloo on the CPU, NCCL with --device cuda, one GPU
    per process); rank 0 alone writes OUT."""
    sinks = dashboards(tensorboard, wandb, wandb_mode)  # a missing package fails here, before any work
    require_torch()
    from toddlerbot.dp.distributed import launched_rank
    from toddlerbot.dp.train import TrainSchedule, train_on_dataset

    if minutes is None and steps is None:
        raise ToddlerbotError("give --minutes or --steps (or both)")
    preset = _preset(config, batch_size, seed, binary_action, resume)
    training_budget(minutes, steps)
    output_dir(out, "--out", [dataset, imagenet_weights])
    main = launched_rank() == 0  # under torchrun only rank 0 prints
    result = train_on_dataset(
        dataset, preset, out, threads, on_open=_announce(dataset, out, main), minutes=minutes, resume=resume,
        schedule=TrainSchedule(max_steps=steps, log_every=log_every, checkpoint_every=checkpoint_every),
        imagenet_weights=imagenet_weights, device=device, dashboards=sinks)
    if main:
        _print_result(result)


def _announce(dataset: Path, out: Path, main: bool):
    """What the trainer calls once the dataset is open: rank 0 says what it trains on."""
    def opened(windows: int) -> None:
        if main:
            console.print(f"dataset {dataset}: {windows} windows; run directory {out}")
    return opened


def _preset(config: str, batch_size: int | None, seed: int | None, binary_actions: list[str] | None, resume: bool):
    """The named configuration, with the global batch ``--batch-size``, the seed ``--seed`` and the binary actions
    ``--binary-action`` give a new run."""
    for flag, value in (("--batch-size", batch_size), ("--seed", seed), ("--binary-action", binary_actions)):
        if resume and value is not None:
            raise ToddlerbotError(f"{flag} sets a new run's {flag[2:].replace('-', ' ')}; a resumed run keeps its own "
                                  f"(drop {flag})")
    preset = PRESETS[config] if batch_size is None else replace(PRESETS[config], batch_size=batch_size)
    preset = preset if seed is None else replace(preset, seed=seed)
    return replace(preset, binary_actions=tuple(binary_actions)) if binary_actions else preset


def _print_result(result) -> None:
    last = result.history[-1] if result.history else {}
    val = last.get("val_loss")
    console.print(f"step {result.step}: train loss {last.get('train_loss', float('nan')):.4f}, validation loss "
                  f"{'-' if val is None else f'{val:.4f}'} (episodes {result.split['val_episodes']}); "
                  f"checkpoint {result.checkpoint}, curve {result.run_dir / 'loss_curve.png'}")


@app.command()
def info(
    checkpoint: Annotated[Path, typer.Argument(help="A checkpoint written by dp train (RUN/checkpoint.pt).")],
    json_output: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
) -> None:
    """Print a checkpoint's training step, size, last losses and configuration."""
    require_torch()

    from toddlerbot.dp.checkpoint import checkpoint_summary

    summary = checkpoint_summary(checkpoint)
    if json_output:
        print(json_text(summary))
        return
    cfg, last = summary["config"], summary["last"] or {}
    console.print(f"{checkpoint}: step {summary['step']}, {summary['parameters'] / 1e6:.2f} M parameters, "
                  f"encoder {cfg['encoder']}, U-Net {cfg['down_dims']}, state {cfg['state_dim']} / action "
                  f"{cfg['action_dim']}, horizon {cfg['horizon']}, {cfg['inference_steps']} {cfg['sampler']} steps")
    if last:
        console.print(f"last losses: train {last['train_loss']:.4f}, validation {last.get('val_loss')}")


@app.command()
def export(
    checkpoint: Annotated[Path, typer.Argument(help="A checkpoint written by dp train (RUN/checkpoint.pt).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="pt: the policy file to write (config and EMA weights "
                                                          "only); onnx: a folder for the two graphs.")],
    export_format: Annotated[Literal["pt", "onnx"], typer.Option(  # dp.onnx_export.FORMATS, which imports torch
        "--format", help="pt (torch, for dp eval / sim run) or onnx (observation encoder and noise U-Net, checked "
                         "against torch).")] = "pt",
    binary_action: BinaryActionOption = None,
) -> None:
    """Write a checkpoint's EMA network alone (no optimiser state): the file to ship or deploy; or, with --format
    onnx, its per-inference networks as ONNX graphs (observation_encoder.onnx, noise_unet.onnx). --binary-action
    sets the actions the exported policy snaps open or closed (replacing the checkpoint's)."""
    require_torch()
    binary = tuple(binary_action) if binary_action else None
    if export_format == "onnx":
        from toddlerbot.dp.onnx_export import export_onnx

        output_dir(out, "--out", [checkpoint])
        paths, report = export_onnx(checkpoint, out, binary)
        for name, path in paths.items():
            console.print(f"wrote {path}: {path.stat().st_size / 1e6:.1f} MB; onnxruntime vs torch on random "
                          f"inputs, max abs difference {report[name]:.2g} (outputs up to "
                          f"{report[name + ' scale']:.2g})", soft_wrap=True)
        return
    from toddlerbot.dp.checkpoint import export_policy

    output_file(out, "--out", [checkpoint])
    written = export_policy(checkpoint, out, binary)
    console.print(f"wrote {written}: {written.stat().st_size / 1e6:.1f} MB (from {checkpoint}, "
                  f"{checkpoint.stat().st_size / 1e6:.1f} MB)")


TaskOption = Annotated[str, typer.Option("--task", help="Task: pick (lift the cube and hold it for 1 s) or wagon "
                                         "(grasp the wagon handle with both hands); NAME:VARIATION for one of its "
                                         "declared scene variations, e.g. wagon:wide.")]
EvalCheckpointOption = Annotated[Path | None, typer.Option(help="Checkpoint to run (default: the one shipped for the "
                                                                "task, if any).")]
EpisodesOption = Annotated[int, typer.Option(min=1, max=10_000, help="Episodes (seeds --seed, --seed+1, ...).")]
SecondsOption = Annotated[float | None, typer.Option(min=0.1, help="Simulated time limit per episode, s (at most "
                                                     "600; default: the task's, pick 8, wagon 6 as the chain's grasp "
                                                     "timeout).")]
VideoOption = Annotated[Path | None, typer.Option(help="MP4 of all episodes: scene camera and head camera, 10 fps.")]


@app.command("eval")
def evaluate(
    task: TaskOption = "pick",
    checkpoint: EvalCheckpointOption = None,
    episodes: EpisodesOption = 50,
    seed: Annotated[int, seed_option(help="First scene seed (use seeds the demonstrations did not).")] = 1000,
    seconds: SecondsOption = None,
    json_output: Annotated[bool, typer.Option("--json", help="Print JSON: success_rate, episodes, inference_ms.")]
    = False,
    video: VideoOption = None,
    threads: Annotated[int, typer.Option(min=1, help="CPU threads for torch.")] = 1,
    device: Annotated[str, typer.Option(help="Torch device for the network: cpu, cuda, ...")] = "cpu",
) -> None:
    """Run a checkpoint closed-loop on a simulated task (50 Hz control, 10 Hz observations) and report success."""
    require_torch(threads)
    from rich.progress import Progress

    from toddlerbot.dp.evaluate import evaluate as run_evaluation
    from toddlerbot.dp.shipped import shipped_checkpoint
    from toddlerbot.tasks import TASKS, task_name

    if task_name(task) not in TASKS:
        raise ToddlerbotError(f"--task {task!r}: expected one of {', '.join(TASKS.names())}")
    if seconds is not None:
        duration(seconds, "--seconds", MAX_EPISODE_SECONDS)
    if video is not None:
        output_file(video, "--video", [checkpoint])
    checkpoint = checkpoint if checkpoint is not None else shipped_checkpoint(task_name(task))
    with Progress(console=console, transient=True) as progress:
        bar = progress.add_task(f"{task} episodes", total=episodes)
        result = run_evaluation(checkpoint, episodes, seed, seconds, task, video_path=video,
                                on_episode=lambda _: progress.advance(bar), device=device)
    summary = result.summary()
    if json_output:
        print(json_text(summary))
        return
    _print_evaluation(summary, task, seed, episodes, checkpoint)
    if video:
        console.print(f"wrote {video}")


def _print_evaluation(summary: dict, task: str, seed: int, episodes: int, checkpoint: Path) -> None:
    """The success rate with its seeds, then what each failed episode ended in."""
    console.print(f"{task}: success {summary['success_rate']:.0%} over seeds {seed}..{seed + episodes - 1} "
                  f"(failed: {summary['failed_seeds'] or 'none'}), {summary['inference_ms']:.1f} ms per inference "
                  f"({checkpoint})")
    for failed, kind in summary["failures"].items():
        console.print(f"  seed {failed}: {kind}")
