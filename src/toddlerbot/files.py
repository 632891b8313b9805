"""File output that never leaves a half-written file: every writer goes through `atomic_write`.

The content is written to a new temporary file with a unique name in the target's folder (so that two writers of
the same target never share it), then moved over the target with `os.replace` (atomic on POSIX and Windows within
one file system). On any error the temporary file is removed and the target keeps its old content.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

_UMASK = os.umask(0)
os.umask(_UMASK)
FILE_MODE = 0o666 & ~_UMASK
"""Permissions of a written file: what `open()` would give under the process umask (mkstemp alone gives 0600)."""


def atomic_write(path: str | Path, write: Callable[[Path], Any]) -> Path:
    """Call ``write(tmp)`` on a fresh temporary file beside ``path`` (same suffix), then move it to ``path``.

    Creates the parent folder. ``write`` must write to the file name it gets (and not append a suffix)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix or ".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        os.chmod(tmp, FILE_MODE)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if exc.filename is None:  # a writer's own error (disk full) names no file: name the target
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    return atomic_write(path, lambda tmp: tmp.write_bytes(data))


def json_text(obj: Any, indent: int | None = None) -> str:
    """``obj`` as JSON that every parser reads: NaN and +-inf (numpy scalars and arrays included) become ``null``
    (``json.dumps`` would write the non-JSON tokens ``NaN`` and ``Infinity``)."""
    return json.dumps(_finite(obj), indent=indent, allow_nan=False)


def _finite(obj: Any) -> Any:
    if isinstance(obj, np.ndarray | np.generic):
        obj = obj.tolist()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def atomic_savez(path: str | Path, arrays: Mapping[str, Any], compressed: bool = False) -> Path:
    """Write ``arrays`` as an ``.npz`` archive to ``path`` atomically, whatever its suffix (numpy appends
    ``.npz`` to file names without it; writing through an open file avoids that)."""
    save = np.savez_compressed if compressed else np.savez

    def write(tmp: Path) -> None:
        with tmp.open("wb") as f:
            save(f, **arrays)

    return atomic_write(path, write)


def save_figure(fig: Any, path: str | Path, dpi: int = 100) -> Path:
    """Lay out a matplotlib figure, write it atomically to ``path`` (format from the suffix, e.g. ``.png``) at
    ``dpi`` dots per inch, and close it (figures otherwise stay in pyplot's registry)."""
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        fig.tight_layout()
        atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".") or "png"))
    finally:
        plt.close(fig)
    return path
