"""Reading a training run's files (checkpoints, the warm start, configuration and records): every read is
size-capped, and a file that is truncated, foreign or random bytes is one line naming it, never a traceback from
msgpack, flax or json."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from toddlerbot.actuation.params_file import MAX_PARAMS_BYTES
from toddlerbot.errors import ToddlerbotError
from toddlerbot.yaml_input import read_bytes, read_text

CONFIG = "config.json"
CHECKPOINTS = "checkpoints"
"""Folder of ``step_<n>.msgpack`` files (`rl.train.save_checkpoint`)."""
WARM_START = "warm_start.msgpack"
ACTION_SPACE = "action_space.npz"
"""The gait reference the run's env used (`GaitReference.arrays`) and its P-gain factors (``kp_stance_scale``,
``kp_swing_scale``), written at the start so that the export carries exactly them."""
MOTOR_PARAMS_RECORD = "motor_params.json"
"""The fitted actuator parameters the run trained on (`motor_params_record`)."""
IMITATION_RECORD = "imitation.jsonl"
METRICS_RECORD = "metrics.jsonl"
REFERENCE_RECORD = "reference.txt"
SMOKE_MARKER = "smoke"
RUN_INPUTS = (CONFIG, CHECKPOINTS, WARM_START, ACTION_SPACE, MOTOR_PARAMS_RECORD, IMITATION_RECORD, METRICS_RECORD,
              REFERENCE_RECORD, SMOKE_MARKER)
"""What a run folder holds that training and export read: an export never writes over one of them."""


def motor_params_record(paths: tuple[str, ...]) -> list[dict]:
    """What a run trained on: each params.json's path, SHA-256 and content (kept in the run and the export, so
    the record survives the file)."""
    record = []
    for name in paths:
        raw = read_bytes(Path(name), "params.json", ToddlerbotError, MAX_PARAMS_BYTES)
        record.append({"file": name, "sha256": hashlib.sha256(raw).hexdigest(), "params": json.loads(raw)})
    return record


def run_inputs(run_dir: Path) -> list[Path]:
    return [run_dir / name for name in RUN_INPUTS]


MAX_CHECKPOINT_BYTES = 1 << 30
"""Largest checkpoint or warm start read, bytes (the CPU recipe's checkpoints are about 10 MB, the one-GPU
recipe's with 8,192 environments' normaliser the same: the networks dominate)."""
MAX_RUN_TEXT_BYTES = 100_000_000
"""Largest text record of a run read, bytes (metrics.jsonl grows by about 2 kB per epoch)."""


def read_payload(path: Path, what: str = "checkpoint") -> dict[str, Any]:
    """The msgpack mapping of a checkpoint (or warm start: ``what``)."""
    from flax import serialization

    data = read_bytes(path, what, ToddlerbotError, MAX_CHECKPOINT_BYTES)
    try:
        payload = serialization.msgpack_restore(data)
    except Exception as exc:  # msgpack raises many types (ValueError, UnicodeDecodeError, ...) for bad bytes
        raise ToddlerbotError(f"{path}: not a {what} ({_reason(exc)})") from None
    if not isinstance(payload, dict):
        raise ToddlerbotError(f"{path}: not a {what} (a {type(payload).__name__}, not a mapping)")
    return payload


def payload_entry(path: Path, payload: dict[str, Any], keys: tuple[str, ...], what: str = "checkpoint") -> Any:
    """``payload[keys[0]][keys[1]]...``, or one line naming the file and the missing entry."""
    node: Any = payload
    for depth, key in enumerate(keys):
        if not isinstance(node, dict) or key not in node:
            raise ToddlerbotError(f"{path}: not a {what} of a walking run (no {'/'.join(keys[:depth + 1])})")
        node = node[key]
    return node


def read_run_text(path: Path, what: str) -> str:
    """A run's text record (configuration, metrics, notes)."""
    return read_text(path, what, ToddlerbotError, MAX_RUN_TEXT_BYTES)


def read_json_lines(path: Path, what: str) -> list[dict]:
    """The records of a ``.jsonl`` file of a run (none when it does not exist)."""
    if not path.is_file():
        return []
    try:
        return [json.loads(line) for line in read_run_text(path, what).splitlines() if line]
    except json.JSONDecodeError as exc:
        raise ToddlerbotError(f"{path}: not a {what} ({_reason(exc)})") from None


def _reason(exc: Exception) -> str:
    return " ".join(str(exc).split())[:200] or f"{type(exc).__name__}: empty or truncated"
