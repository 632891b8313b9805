"""Console shared by the CLI modules (wide enough for tables when piped to a file), and saving a result that must
not be lost."""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from rich.console import Console

console = Console(width=None if sys.stdout.isatty() else 160)


def save_or_fallback(save: Callable[[Path], object], path: Path | None, what: str) -> Path:
    """``save(path)``; if that fails (disk full, folder removed meanwhile) or `path` is None, ``save`` to a new
    named temporary file instead. Says where it went: the log of a run on the robot is never lost."""
    problem = "no file was named"
    if path is not None:
        try:
            save(path)
            console.print(f"wrote {what} to {path}", highlight=False, soft_wrap=True)
            return path
        except OSError as exc:
            problem = f"cannot write {path}: {exc.strerror or exc}"
    fd, name = tempfile.mkstemp(prefix="toddlerbot-", suffix=path.suffix if path is not None else ".npz")
    os.close(fd)
    save(Path(name))
    console.print(f"wrote {what} to {name} ({problem})", highlight=False, soft_wrap=True)
    return Path(name)
