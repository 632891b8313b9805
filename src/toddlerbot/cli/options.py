"""Checks of CLI option values that typer cannot express, each failing with a one-line `ToddlerbotError`
before any work starts (a run is never started only to fail at its end)."""

from __future__ import annotations

import math
import os
from pathlib import Path

from toddlerbot.errors import ToddlerbotError


def positive(value: float, option: str, unit: str) -> float:
    """`value` if it is a finite number > 0 (NaN, inf, 0 and negatives are refused, naming the option)."""
    if not (math.isfinite(value) and value > 0):
        raise ToddlerbotError(f"{option} {value}: expected a finite number of {unit} > 0")
    return value


def writable(path: Path, option: str) -> Path:
    """`path` if a file can be written there (its nearest existing folder is writable, it is not a folder)."""
    if path.is_dir():
        raise ToddlerbotError(f"{option} {path}: is a directory, expected a file name")
    existing = next((p for p in path.absolute().parents if p.exists()), Path("/"))
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK) or (
            path.exists() and not os.access(path, os.W_OK)):
        raise ToddlerbotError(f"{option} {path}: cannot write there ({existing} is not a writable folder)")
    return path
