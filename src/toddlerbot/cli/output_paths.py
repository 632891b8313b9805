"""The one check of every path a command writes, run before any work starts. One rule for all commands:

- the folder that will hold the output must exist (a typo in a path is refused, not created as a new tree); an
  output folder itself (``--out RUN``) may be new, and a command creates its own default location;
- an output never resolves to one of the command's inputs (a manifest, a log, a run, a checkpoint, a dataset),
  nor lies inside an input folder;
- an output never lies inside the installed ``toddlerbot`` package (shipping a file into it is an explicit
  maintainer's step: ``rl export --ship``);
- the place is shown writable by creating and removing a probe file (``os.access`` says yes to root under /proc);
  an existing folder where a file is expected, a file where a folder is expected, or a device is refused.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

import toddlerbot
from toddlerbot.errors import ToddlerbotError

PACKAGE_DIR = Path(toddlerbot.__file__).resolve().parent
"""The installed package (``src/toddlerbot`` in a source checkout): no command writes into it unasked."""

Inputs = Iterable[str | Path | None]
"""The files and folders a command reads (None entries are skipped: options not given)."""


def output_file(path: Path, option: str, inputs: Inputs = (), into_package: bool = False) -> Path:
    """`path` once it is shown to be a new or regular file that the command may write (the rules above);
    ``into_package``: the one caller that ships a file into the package says so."""
    if path.exists() and not path.is_file():
        kind = "a directory" if path.is_dir() else "a special file"
        raise ToddlerbotError(f"{option} {path}: is {kind}, expected the name of a regular file to write")
    _check_place(path, option, inputs, into_package)
    _probe(path.absolute().parent, path.name, option, path)
    return path


def output_dir(path: Path, option: str, inputs: Inputs = (), default: bool = False, empty: str | None = None) -> Path:
    """`path` as a folder to write files into: an existing folder, or a new one whose parent exists (``default``:
    the command's own default location, whose parents are created). Shown writable with a probe file. ``empty``:
    the folder must be new or empty (a dataset is written whole), and this says how to replace one."""
    if path.exists() and not path.is_dir():
        raise ToddlerbotError(f"{option} {path}: is not a folder, expected a folder to write into")
    if empty is not None and path.is_dir() and any(path.iterdir()):
        raise ToddlerbotError(f"{option} {path}: exists and is not empty{empty}")
    _check_place(path, option, inputs, into_package=False)
    if default:
        path.absolute().parent.mkdir(parents=True, exist_ok=True)
    _probe(path.absolute() if path.is_dir() else path.absolute().parent, path.name, option, path)
    return path


def source_checkout(option: str) -> Path:
    """The root of the source checkout the package runs from (``pip install -e`` of a git clone), or one line:
    ``option`` writes into the package, which only a maintainer does, from a checkout whose change git shows."""
    root = PACKAGE_DIR.parents[1]
    if PACKAGE_DIR.parent.name != "src" or not (root / "pyproject.toml").is_file() or not (root / ".git").exists():
        raise ToddlerbotError(f"{option} writes into the package at {PACKAGE_DIR}, which is not in a source checkout "
                              "(a git clone installed with pip install -e); write elsewhere with --out")
    return root


def not_an_input(path: Path, option: str, inputs: Inputs) -> Path:
    """`path` unless it is one of `inputs` or lies inside an input folder (for inputs known only once the first
    input is read, e.g. the logs a manifest names)."""
    for given in inputs:
        if given is not None and _overlaps(path, Path(given)):
            raise ToddlerbotError(f"{option} {path}: would overwrite this command's input {given}; write elsewhere")
    return path


def _check_place(path: Path, option: str, inputs: Inputs, into_package: bool) -> None:
    not_an_input(path, option, inputs)
    if not into_package and path.resolve().is_relative_to(PACKAGE_DIR):
        raise ToddlerbotError(f"{option} {path}: is inside the installed toddlerbot package ({PACKAGE_DIR}); "
                              "write elsewhere")


def _overlaps(output: Path, given: Path) -> bool:
    """The output is the input (by path, or the same file through a link) or lies inside an input folder."""
    out, source = output.resolve(), given.resolve()
    if out == source or (source.is_dir() and out.is_relative_to(source)):
        return True
    try:
        return os.path.samefile(output, given)
    except OSError:  # one of them does not exist (yet)
        return False


def _probe(folder: Path, name: str, option: str, path: Path) -> None:
    existing = next(p for p in (folder, *folder.parents) if p.exists())
    if not existing.is_dir():
        raise ToddlerbotError(f"{option} {path}: cannot write there ({existing} is not a folder)")
    if existing != folder:
        raise ToddlerbotError(f"{option} {path}: folder {path.parent} does not exist; create it first (mkdir -p "
                              f"{path.parent})")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{name}.", suffix=".probe", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ToddlerbotError(f"{option} {path}: cannot write there ({exc.strerror or exc})") from None
