"""Training loop: split by episode, fit the normalisers on the training episodes, optimise the noise-prediction
loss with AdamW, keep an EMA copy, evaluate on the validation episodes, checkpoint, plot the loss curve.

A run directory holds ``checkpoint.pt`` (latest, resumable), ``config.json`` (the config, readable),
``split.json`` (the episodes of each side), ``metrics.json`` (the history), ``metrics.jsonl`` (the same records,
written as they come), ``tensorboard/`` (them as TensorBoard scalars ``dp/<key>``, `toddlerbot.metrics`) and
``loss_curve.png``.

Launched by ``torchrun`` with several processes, `train` runs data-parallel (`toddlerbot.dp.distributed`): every
rank draws the same global batch of windows and the same noise, steps and crops, and trains on its share of them
under DistributedDataParallel; rank 0 alone writes the run directory.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from toddlerbot.dp.checkpoint import (
    CheckpointError,
    TrainingState,
    load_training_state,
    new_training_state,
    save_checkpoint,
)
from toddlerbot.dp.config import DPConfig, DPConfigError
from toddlerbot.dp.data import (
    DatasetError,
    WindowDataset,
    batch_keys,
    check_sample,
    gather,
    split_by_episode,
    value_ranges,
)
from toddlerbot.dp.distributed import DataParallel, batch_rows, join
from toddlerbot.dp.ema import EMA
from toddlerbot.dp.imagenet import load_imagenet_weights
from toddlerbot.dp.plot import plot_loss_curve
from toddlerbot.files import atomic_write_text
from toddlerbot.metrics import Dashboards, MetricsLogger
from toddlerbot.yaml_input import read_text

CHECKPOINT = "checkpoint.pt"
VAL_SEED = 12345
"""Noise and steps of the validation loss come from this fixed seed, so evaluations compare like with like."""


@dataclass(frozen=True)
class TrainSchedule:
    """When to stop, log, validate and save (in optimiser steps unless stated)."""

    max_steps: int | None = None
    """Stop at this total step count (a resumed run counts from its checkpoint)."""
    minutes: float | None = None
    """Stop after the step that passes this wall time of this invocation."""
    log_every: int = 50
    val_batches: int = 4
    """Validation batches per evaluation (of the validation episodes)."""
    checkpoint_every: int = 500

    def __post_init__(self) -> None:
        # a budget must end and must run: NaN minutes trained forever, -5 steps saved a NaN-loss checkpoint
        if self.max_steps is not None and self.max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {self.max_steps}")
        if self.minutes is not None and not (math.isfinite(self.minutes) and self.minutes > 0):
            raise ValueError(f"minutes must be a finite number > 0, got {self.minutes}")


@dataclass(frozen=True)
class TrainResult:
    run_dir: Path
    checkpoint: Path
    step: int
    history: list[dict[str, float]]
    split: dict[str, list[int]]


def _batch(dataset: WindowDataset, indices: list[int], keys: tuple[str, ...],
           device: torch.device) -> dict[str, torch.Tensor]:
    return {k: v.to(device, non_blocking=True) for k, v in gather(dataset, indices, keys).items()}


def _mean(losses: list[torch.Tensor], parallel: DataParallel | None) -> float:
    """Mean training loss since the last record, over all ranks (each rank's loss is its share of the global one)."""
    mean = torch.stack(losses).double().mean()
    if parallel is not None:
        mean = parallel.sum(mean) / parallel.world_size
    return float(mean)


@torch.no_grad()
def validation_loss(state: TrainingState, dataset: WindowDataset, batches: int) -> float | None:
    """Mean EMA noise-prediction loss over the first ``batches`` batches of ``dataset`` (fixed noise seed)."""
    if len(dataset) == 0:
        return None
    cfg = state.policy.config
    keys = batch_keys(cfg.uses_images)
    generator = torch.Generator().manual_seed(VAL_SEED)
    device = next(state.ema.model.parameters()).device
    losses = []
    for b in range(batches):
        indices = list(range(b * cfg.batch_size, min((b + 1) * cfg.batch_size, len(dataset))))
        if not indices:
            break
        losses.append(float(state.ema.model.loss(_batch(dataset, indices, keys, device), generator)))
    return float(np.mean(losses))


def _start(dataset: WindowDataset, config: DPConfig, run_dir: Path, resume: bool, imagenet_weights: Path | None,
           device: torch.device, world_size: int, writes: bool):
    """The training state (new, or the checkpoint's), the split and the global batch; ``writes``: this process writes
    the run directory (rank 0)."""
    if len(dataset) == 0:
        raise DatasetError("the window dataset is empty")
    sample = dataset[0]
    state_dim, action_dim = check_sample(sample, config.n_obs_steps, config.horizon, config.uses_images)
    checkpoint = run_dir / CHECKPOINT
    if resume:
        state = load_training_state(checkpoint, device)
        config = state.policy.config
        if (config.state_dim, config.action_dim) != (state_dim, action_dim):
            raise DatasetError(f"{checkpoint}: trained on state/action dims {config.state_dim}/{config.action_dim}, "
                               f"the dataset has {state_dim}/{action_dim}")
    train_set, val_set, split = split_by_episode(dataset, config.val_fraction, config.seed)
    global_batch = min(config.batch_size, len(train_set))
    batch_rows(global_batch, world_size, 0)  # refused before anything is written
    split_file = run_dir / "split.json"
    if resume:
        saved = json.loads(read_text(split_file, "episode split", DatasetError)) if split_file.is_file() else None
        if saved != split:
            raise DatasetError(f"{split_file}: the dataset's episodes differ from the run being resumed")
        return state, train_set, val_set, split, global_batch
    if checkpoint.exists():
        raise CheckpointError(f"{checkpoint}: a run already exists here; resume it (--resume) or choose another "
                              "directory")
    config = config.with_dims(state_dim, action_dim, getattr(dataset, "state_names", ()),
                              getattr(dataset, "action_names", ()))
    state = new_training_state(config, value_ranges(train_set), device)
    if imagenet_weights is not None:
        if config.encoder != "resnet18":
            raise DPConfigError(f"ImageNet weights need encoder resnet18 (the config has {config.encoder})")
        load_imagenet_weights(state.policy.encoder, imagenet_weights)
        state.ema = EMA(state.policy, config.ema_decay)
    if writes:
        run_dir.mkdir(parents=True, exist_ok=True)
        atomic_write_text(run_dir / "config.json", json.dumps(json.loads(config.to_json()), indent=2) + "\n")
        atomic_write_text(split_file, json.dumps(split) + "\n")
    return state, train_set, val_set, split, global_batch


def train(dataset: WindowDataset, config: DPConfig, out_dir: str | Path, minutes: float | None = None,
          resume: bool = False, schedule: TrainSchedule | None = None, show_progress: bool = True,
          imagenet_weights: str | Path | None = None, device: str = "cpu",
          dashboards: Dashboards | None = None) -> TrainResult:
    """Train (or, with ``resume``, continue) a diffusion policy on ``dataset``; checkpoints go to ``out_dir``.

    ``imagenet_weights``: a local torchvision ResNet-18 state dict to start the ``resnet18`` encoder from
    (`imagenet.load_imagenet_weights`); without it the encoder trains from scratch.
    ``device``: ``cpu`` or a torch device such as ``cuda`` (batches are assembled on the CPU and moved there).
    Stops at ``minutes`` of wall time or ``schedule.max_steps`` (at least one of them must be given).
    ``config``'s state/action dims are taken from the dataset; on resume the checkpoint's config is used.
    Each record (``step``, ``train_loss``, ``val_loss``, ``learning_rate``, ``steps_per_s``, ``seconds``) goes to
    ``metrics.jsonl``, TensorBoard (``dashboards`` default) and, with ``dashboards.wandb``, W&B, at x = its step.
    Under a launcher with ``WORLD_SIZE`` > 1 (torchrun) the run is data-parallel (`toddlerbot.dp.distributed`):
    ``config.batch_size`` is the global batch, split evenly over the processes; only rank 0 writes files, validates
    and holds the records (``history``).
    """
    schedule = schedule or TrainSchedule()
    if minutes is not None:
        schedule = replace(schedule, minutes=minutes)
    if schedule.max_steps is None and schedule.minutes is None:
        raise ValueError("train needs minutes or schedule.max_steps")
    target = torch.device(device)
    if target.type == "cuda":
        if not torch.cuda.is_available():
            raise DPConfigError(f"device {device!r}: torch {torch.__version__} sees no CUDA GPU")
        torch.backends.cuda.matmul.allow_tf32 = torch.backends.cudnn.allow_tf32 = True
    parallel = join(target)
    try:
        return _train(dataset, config, Path(out_dir), resume, schedule, show_progress,
                      None if imagenet_weights is None else Path(imagenet_weights),
                      target if parallel is None else parallel.device, dashboards, parallel)
    finally:
        if parallel is not None:
            parallel.leave()


def _train(dataset: WindowDataset, config: DPConfig, run_dir: Path, resume: bool, schedule: TrainSchedule,
           show_progress: bool, weights: Path | None, target: torch.device, dashboards: Dashboards | None,
           parallel: DataParallel | None) -> TrainResult:
    main = parallel is None or parallel.main
    state, train_set, val_set, split, global_batch = _start(
        dataset, config, run_dir, resume, weights, target, 1 if parallel is None else parallel.world_size, main)
    cfg = state.policy.config
    keys = batch_keys(cfg.uses_images)
    n_train = len(train_set)
    rows = slice(None) if parallel is None else parallel.rows(global_batch)
    model: torch.nn.Module = state.policy
    if parallel is not None:
        parallel.agree("(training windows, validation windows, step, episode split)",
                       (n_train, len(val_set), state.step, split))
        model = parallel.wrap(state.policy)  # rank 0's weights on every rank
        parallel.broadcast(state.ema.model)
    started = time.perf_counter()
    deadline = None if schedule.minutes is None else started + 60.0 * schedule.minutes
    checkpoint = run_dir / CHECKPOINT
    losses: list[torch.Tensor] = []  # kept on the device: reading each one would wait for the GPU every step
    since = (state.step, started)

    def record() -> None:
        nonlocal since
        train_loss = _mean(losses, parallel)  # every rank takes part
        losses.clear()
        if main:
            now = time.perf_counter()
            entry = {"step": state.step, "train_loss": train_loss,
                     "val_loss": validation_loss(state, val_set, schedule.val_batches),
                     "learning_rate": float(state.optimizer.param_groups[0]["lr"]),
                     "steps_per_s": (state.step - since[0]) / max(now - since[1], 1e-9), "seconds": now - started}
            state.history.append(entry)
            metrics.log("dp", entry, step=state.step)
        since = (state.step, time.perf_counter())  # validation time is not training time

    def time_is_up() -> bool:
        if deadline is None:
            return False
        up = time.perf_counter() >= deadline
        return up if parallel is None else parallel.decide(up)  # all ranks stop at the same step

    state.policy.train()
    logger = (MetricsLogger.open(run_dir, {"dp": "metrics.jsonl"}, dashboards, job_type="dp-train",
                                 config=json.loads(cfg.to_json())) if main else contextlib.nullcontext())
    with logger as metrics:
        with Progress(TextColumn("dp train"), BarColumn(), TextColumn("{task.fields[info]}"), TimeElapsedColumn(),
                      disable=not (show_progress and main)) as bar:
            task = bar.add_task("train", total=schedule.max_steps, completed=state.step, info="")
            while True:
                if schedule.max_steps is not None and state.step >= schedule.max_steps:
                    break
                if time_is_up():
                    break
                # every rank draws the whole global batch and its noise, and trains on its own rows of them
                indices = torch.randperm(n_train, generator=state.data_rng)[:global_batch].tolist()
                batch = _batch(train_set, indices[rows], keys, target)
                draws = state.policy.draw(batch, global_batch).part(rows)
                total, count = model(batch, draws)
                if parallel is None:
                    loss = total / count.clamp(min=1.0)
                else:  # DDP averages gradients over ranks: this rank's share of the global mean
                    loss = total * parallel.world_size / parallel.sum(count).clamp(min=1.0)
                state.optimizer.zero_grad(set_to_none=True)
                loss.backward()
                state.optimizer.step()
                state.ema.update(state.policy)
                state.step += 1
                losses.append(loss.detach())
                if state.step % schedule.log_every == 0:
                    record()
                    if main:
                        last = state.history[-1]
                        val = "-" if last["val_loss"] is None else f"{last['val_loss']:.4f}"
                        bar.update(task, info=f"step {state.step} loss {last['train_loss']:.4f} val {val}")
                if main and state.step % schedule.checkpoint_every == 0:
                    save_checkpoint(checkpoint, state)
                bar.update(task, completed=state.step)
        if losses:
            record()
    if main:
        save_checkpoint(checkpoint, state)
        atomic_write_text(run_dir / "metrics.json", json.dumps(state.history, indent=1) + "\n")
        if state.history:
            plot_loss_curve(state.history, run_dir / "loss_curve.png")
    return TrainResult(run_dir, checkpoint, state.step, list(state.history), split)


def train_on_dataset(path: Path, config: DPConfig, out_dir: Path, threads: int,
                     on_open: Callable[[int], None] | None = None, **options) -> TrainResult:
    """`train` (with `options`) on the dataset at `path` (LeRobot v3.0 directory or decoded .npz) read as windows of
    `config`; torch uses `threads` CPU threads for this call only (in-process callers keep their setting).
    `on_open` hears the number of windows before training starts."""
    from toddlerbot.dp import data  # looked up at call time: tests replace the reader

    previous_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        windows = data.open_window_dataset(path, config.n_obs_steps, config.horizon)
        if on_open is not None:
            on_open(len(windows))
        return train(windows, config, out_dir, **options)
    finally:
        torch.set_num_threads(previous_threads)
