"""Helpers of the training-dashboard tests: TensorBoard's own event reader, and the fake ``wandb`` module."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np

FAKE_WANDB_DIR = Path(__file__).parent / "fake_wandb"


def read_scalars(log_dir: Path) -> dict[str, list[tuple[int, float]]]:
    """Every scalar of the event files in ``log_dir`` (all of them: a resumed run adds a file), as TensorBoard
    reads them: tag -> [(step, value)]."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    accumulator = EventAccumulator(str(log_dir), size_guidance={"scalars": 0})
    accumulator.Reload()
    return {tag: [(e.step, e.value) for e in accumulator.Scalars(tag)] for tag in accumulator.Tags()["scalars"]}


def read_jsonl(path: Path) -> list[dict]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line]


def numbers(record: dict) -> dict[str, float]:
    """The record's scalars as the sinks see them (numbers, not booleans, strings or None)."""
    return {k: float(v) for k, v in record.items()
            if isinstance(v, int | float) and not isinstance(v, bool)}


def as_float32(value: float) -> float:
    """A TensorBoard scalar is stored as a 32-bit float."""
    return float(np.float32(value))


def expected_scalars(stream: str, records: list[dict], steps: list[int]) -> dict[str, list[tuple[int, float]]]:
    """What TensorBoard must hold for these JSON-line records: ``<stream>/<key>`` -> [(step, float32 value)]."""
    expected: dict[str, list[tuple[int, float]]] = {}
    for record, step in zip(records, steps, strict=True):
        for key, value in numbers(record).items():
            expected.setdefault(f"{stream}/{key}", []).append((step, as_float32(value)))
    return expected


def fake_wandb(monkeypatch):
    """Install the fake ``wandb`` module (`fake_wandb/wandb.py`) for this test; returns it (``.CALLS``)."""
    spec = importlib.util.spec_from_file_location("wandb", FAKE_WANDB_DIR / "wandb.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setitem(sys.modules, "wandb", module)
    monkeypatch.delenv("FAKE_WANDB_LOG", raising=False)
    return module


def wandb_logs(calls: list[tuple[str, dict]], stream: str) -> list[dict]:
    """The data of the fake W&B run's ``log`` calls for one stream (keys without the stream prefix)."""
    prefix = f"{stream}/"
    return [{k[len(prefix):]: v for k, v in kw["data"].items() if k.startswith(prefix)}
            for name, kw in calls if name == "log" and any(k.startswith(prefix) for k in kw["data"])]
