"""Reading input files that a user (or an attacker) hands to a command: bounded size (every file a command reads
is read through `read_bytes`/`read_text`/`read_yaml`, or checked by `sized_file` before a library opens it), UTF-8,
bounded YAML alias expansion, one-line errors naming the file.

``yaml.safe_load`` never runs code, but it happily decodes a 50 MB file for minutes and builds "billion laughs"
documents whose aliases expand to exponentially many nodes once validated. `read_yaml` refuses both first.
"""

from __future__ import annotations

import stat
from pathlib import Path

import yaml

from toddlerbot.errors import ToddlerbotError

MAX_YAML_BYTES = 4_000_000
"""Default size cap, bytes (the packaged robot spec is about 40 kB)."""
MAX_YAML_NODES = 1_000_000
"""Largest number of nodes a document may expand to once every alias is followed."""


def read_yaml(path: str | Path, what: str, error: type[ToddlerbotError] = ToddlerbotError,
              max_bytes: int = MAX_YAML_BYTES) -> object:
    """The parsed document of `path`; `error` (one line: the file, then the problem) for a missing, oversized,
    non-UTF-8, malformed or alias-bomb file. `what` names the kind of file in messages, e.g. "robot spec"."""
    return parse_yaml(read_text(path, what, error, max_bytes, "a YAML text file"), str(path), what, error)


def read_text(path: str | Path, what: str, error: type[ToddlerbotError] = ToddlerbotError,
              max_bytes: int = MAX_YAML_BYTES, kind: str = "a text file") -> str:
    """The UTF-8 text of `path`, read up to `max_bytes` (so /dev/zero or a FIFO cannot make it read forever);
    `error` naming the file for a missing, oversized or non-UTF-8 one. `kind` says what a `what` is in messages."""
    path = Path(path)
    data = read_bytes(path, what, error, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text (byte {exc.start}); a {what} is {kind}") from None


def read_bytes(path: str | Path, what: str, error: type[ToddlerbotError] = ToddlerbotError,
               max_bytes: int = MAX_YAML_BYTES) -> bytes:
    """The bytes of `path`, read up to `max_bytes`; `error` naming the file for a missing or oversized one."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read {what} ({exc.strerror or exc})") from None
    if len(data) > max_bytes:
        raise error(f"{path}: {_size(path, max_bytes)} is too large for a {what} (at most {max_bytes} bytes)")
    return data


def sized_file(path: str | Path, what: str, error: type[ToddlerbotError] = ToddlerbotError,
               max_bytes: int = MAX_YAML_BYTES) -> Path:
    """`path` if it is a regular file of at most `max_bytes`, for a reader that opens it itself (numpy, torch):
    a device or FIFO (/dev/zero) and an oversized file are refused before a byte is read."""
    path = Path(path)
    try:
        info = path.stat()
    except OSError as exc:
        raise error(f"{path}: cannot read {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{path}: not a regular file; a {what} is a file")
    if info.st_size > max_bytes:
        raise error(f"{path}: {info.st_size} bytes is too large for a {what} (at most {max_bytes} bytes)")
    return path


def _size(path: Path, max_bytes: int) -> str:
    """The file's size in bytes, or "more than `max_bytes` bytes" for a device or FIFO (no size to report)."""
    size = path.stat().st_size
    return f"{size} bytes" if size > max_bytes else f"more than {max_bytes} bytes"


def parse_yaml(text: str, source: str, what: str, error: type[ToddlerbotError] = ToddlerbotError) -> object:
    """`read_yaml` for text already in memory; `source` names it in messages."""
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        if node is not None and _expanded_size(node) > MAX_YAML_NODES:
            raise error(f"{source}: YAML aliases expand to more than {MAX_YAML_NODES} nodes; not a {what}")
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise error(f"{source}: not valid YAML ({' '.join(str(exc).split())})") from None
    except RecursionError:
        raise error(f"{source}: YAML nested too deeply; not a {what}") from None


def _expanded_size(root: yaml.Node) -> int:
    """Nodes of the document with every alias followed (shared nodes counted once per use), computed once per
    distinct node so that an alias bomb costs time linear in its text."""
    sizes: dict[int, int] = {}

    def size(node: yaml.Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        sizes[key] = 1  # a node that contains itself (recursive alias) counts once
        if isinstance(node, yaml.SequenceNode):
            total = 1 + sum(size(child) for child in node.value)
        elif isinstance(node, yaml.MappingNode):
            total = 1 + sum(size(k) + size(v) for k, v in node.value)
        else:
            total = 1
        sizes[key] = min(total, MAX_YAML_NODES + 1)
        return sizes[key]

    return size(root)
