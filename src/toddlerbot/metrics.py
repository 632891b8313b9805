"""Training metrics, one record at a time, fanned out to every sink: JSON lines, TensorBoard event files and,
when asked for, Weights & Biases.

`MetricsLogger.log(stream, record, step)` is the one place a training loop reports a record (a dict of numbers
and labels). Each sink receives the same record:

* `JsonlSink`: the record, whole and unchanged, as one line of the stream's file (``metrics.jsonl``, ...);
* `TensorBoardSink`: each number as the scalar ``<stream>/<key>`` at ``step`` (tensorboardX, no TensorFlow),
  in ``<run>/tensorboard/``; open with ``tensorboard --logdir <run>``;
* `WandbSink`: the same numbers as ``<stream>/<key>`` with ``<stream>/step`` as their x axis (the optional
  ``wandb`` package, extra ``[wandb]``; offline mode writes ``<run>/wandb/`` for ``wandb sync``).

Strings, booleans and ``None`` reach the JSON lines only. Nothing here needs JAX or PyTorch: ``rl`` (JAX) and
``dp`` (PyTorch) both use it.
"""

from __future__ import annotations

import json
import numbers
import os
import secrets
import sys
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Protocol

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_text
from toddlerbot.yaml_input import read_text

TENSORBOARD_DIR = "tensorboard"
"""Folder of a run directory holding its TensorBoard event files (one file per training call)."""
WANDB_RUN_ID = "wandb_run_id"
"""File of a run directory holding its W&B run id, so that a resumed training continues the same W&B run."""
WANDB_MODES = ("online", "offline")
DEFAULT_WANDB_PROJECT = "toddlerbot"


@dataclass(frozen=True)
class Dashboards:
    """Which sinks besides the JSON lines a training writes to (the CLI's ``--tensorboard/--no-tensorboard``,
    ``--wandb``, ``--wandb-mode``)."""

    tensorboard: bool = True
    wandb: bool = False
    wandb_mode: str | None = None
    """``online`` or ``offline``; None: the ``WANDB_MODE`` variable, else W&B's default (online)."""
    wandb_project: str | None = None
    """None: the ``WANDB_PROJECT`` variable, else ``toddlerbot``."""

    def __post_init__(self) -> None:
        if self.wandb_mode is not None and self.wandb_mode not in WANDB_MODES:
            raise ToddlerbotError(f"--wandb-mode {self.wandb_mode!r}: expected {' or '.join(WANDB_MODES)}")

    def check(self) -> None:
        """Fail now, in one line, when the package of a chosen sink is missing (before any training starts)."""
        if self.tensorboard:
            import_tensorboardx()
        if self.wandb:
            import_wandb()


NO_DASHBOARDS = Dashboards(tensorboard=False)
"""JSON lines only."""


def scalars(record: Mapping[str, Any]) -> dict[str, float]:
    """The record's numbers (booleans, strings and ``None`` left out), as floats."""
    return {k: float(v) for k, v in record.items() if isinstance(v, numbers.Real) and not isinstance(v, bool)}


class Sink(Protocol):
    def write(self, stream: str, record: Mapping[str, Any], step: int) -> None: ...

    def close(self, failed: bool = False) -> None: ...


class JsonlSink:
    """Appends each record of a stream named in ``files`` to that file as one JSON line (other streams: none)."""

    def __init__(self, files: Mapping[str, Path]) -> None:
        self.files = {stream: Path(path) for stream, path in files.items()}

    def write(self, stream: str, record: Mapping[str, Any], step: int) -> None:
        path = self.files.get(stream)
        if path is not None:
            with path.open("a", encoding="utf-8") as f:
                f.write(json.dumps(dict(record)) + "\n")

    def close(self, failed: bool = False) -> None:
        pass


def import_tensorboardx() -> ModuleType:
    """tensorboardX, or a one-line error naming the extras that bring it.

    tensorboardX's writer imports PyTorch whenever it is installed (to accept torch tensors): 1.0 s and 191 MB
    of peak memory (torch 2.13 CPU, benchmarks/bench_tensorboardx_import.py). A process that has not loaded PyTorch
    (RL training, which must not need it) does not pay for it here: PyTorch is hidden while tensorboardX loads, and
    numbers never reach it afterwards (tensorboardX imports torch again only for a torch tensor)."""
    if "tensorboardX" in sys.modules:
        return sys.modules["tensorboardX"]
    hide_torch = "torch" not in sys.modules
    if hide_torch:
        sys.modules["torch"] = None  # type: ignore[assignment]  # `import torch` raises ImportError meanwhile
    try:
        import tensorboardX
    except ImportError as exc:
        raise ToddlerbotError(f"TensorBoard logging needs tensorboardX (extras [train] and [dp]; pip install "
                              f"tensorboardX), or turn it off with --no-tensorboard ({exc})") from None
    finally:
        if hide_torch and sys.modules.get("torch", 0) is None:
            del sys.modules["torch"]
    return tensorboardX


class TensorBoardSink:
    """Each number of a record as the scalar ``<stream>/<key>`` at ``step``; flushed after every record, so a
    running TensorBoard shows it at once. A resumed training adds a new event file to the same folder."""

    def __init__(self, log_dir: Path) -> None:
        tensorboardx = import_tensorboardx()
        self.log_dir = Path(log_dir)
        # the event file is named after the second it was opened in: two training calls within one second (a quick
        # resume) would share a name and the second would overwrite the first, so the nanoseconds make it unique
        self.writer = tensorboardx.SummaryWriter(logdir=str(self.log_dir), filename_suffix=f".{time.time_ns()}")

    def write(self, stream: str, record: Mapping[str, Any], step: int) -> None:
        for key, value in scalars(record).items():
            self.writer.add_scalar(f"{stream}/{key}", value, global_step=int(step))
        self.writer.flush()

    def close(self, failed: bool = False) -> None:
        self.writer.close()


def import_wandb() -> ModuleType:
    """The wandb package, or a one-line error naming the extra."""
    try:
        import wandb
    except ImportError:
        raise ToddlerbotError("--wandb needs the wandb package, which is not installed: pip install "
                              "'toddlerbot[wandb]' (or leave out --wandb)") from None
    return wandb


class WandbSink:
    """The numbers of each record as ``<stream>/<key>``, plotted against ``<stream>/step``, in one W&B run per
    run directory (its id kept in ``wandb_run_id``: a resumed training continues it). Local files go to
    ``<run>/wandb/``."""

    def __init__(self, run_dir: Path, job_type: str, config: Mapping[str, Any] | None = None,
                 mode: str | None = None, project: str | None = None) -> None:
        wandb = import_wandb()
        run_dir = Path(run_dir)
        id_file = run_dir / WANDB_RUN_ID
        run_id = read_text(id_file, "W&B run id", max_bytes=1000).strip() if id_file.is_file() else ""
        if not run_id:
            run_id = secrets.token_hex(6)
            atomic_write_text(id_file, run_id + "\n")
        try:
            self.run = wandb.init(project=project or os.environ.get("WANDB_PROJECT") or DEFAULT_WANDB_PROJECT,
                                  name=run_dir.resolve().name, id=run_id, resume="allow", dir=str(run_dir),
                                  job_type=job_type, config=dict(config or {}), mode=mode)
        except Exception as exc:  # wandb raises its own types (no login, no network, ...)
            reason = " ".join(str(exc).split()) or type(exc).__name__
            raise ToddlerbotError(f"--wandb: W&B could not start the run ({reason}); --wandb-mode offline logs "
                                  f"locally for a later `wandb sync`") from None
        self.streams: set[str] = set()

    def write(self, stream: str, record: Mapping[str, Any], step: int) -> None:
        if stream not in self.streams:
            self.streams.add(stream)
            self.run.define_metric(f"{stream}/step")
            self.run.define_metric(f"{stream}/*", step_metric=f"{stream}/step")
        self.run.log({**{f"{stream}/{k}": v for k, v in scalars(record).items()}, f"{stream}/step": int(step)})

    def close(self, failed: bool = False) -> None:
        self.run.finish(exit_code=1 if failed else 0)


class MetricsLogger:
    """Sends every record to all its sinks; a context manager that closes them (flushing the event files)."""

    def __init__(self, sinks: Iterable[Sink]) -> None:
        self.sinks = list(sinks)

    @classmethod
    def open(cls, run_dir: str | Path, jsonl: Mapping[str, str], dashboards: Dashboards | None = None,
             job_type: str = "train", config: Mapping[str, Any] | None = None) -> MetricsLogger:
        """The sinks of a run directory: ``jsonl`` maps streams to file names in it; ``dashboards`` (default: JSON
        lines and TensorBoard) adds ``<run>/tensorboard/`` and W&B (``job_type``, ``config``)."""
        run_dir = Path(run_dir)
        dashboards = Dashboards() if dashboards is None else dashboards
        dashboards.check()
        sinks: list[Sink] = [JsonlSink({stream: run_dir / name for stream, name in jsonl.items()})]
        try:
            if dashboards.tensorboard:
                sinks.append(TensorBoardSink(run_dir / TENSORBOARD_DIR))
            if dashboards.wandb:
                sinks.append(WandbSink(run_dir, job_type, config, dashboards.wandb_mode, dashboards.wandb_project))
        except BaseException:
            cls(sinks).close(failed=True)
            raise
        return cls(sinks)

    def log(self, stream: str, record: Mapping[str, Any], step: int) -> None:
        """Write ``record`` to every sink, its numbers at x = ``step`` (environment or optimiser steps)."""
        for sink in self.sinks:
            sink.write(stream, record, step)

    def close(self, failed: bool = False) -> None:
        errors = []
        for sink in self.sinks:
            try:
                sink.close(failed)
            except Exception as exc:  # close the others all the same
                errors.append(exc)
        self.sinks = []
        if errors and not failed:  # while a failure propagates, it is the error to report
            raise errors[0]

    def __enter__(self) -> MetricsLogger:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(failed=exc_type is not None)
