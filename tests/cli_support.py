"""Running ``toddlerbot ARGS`` in the test's process as a user's shell would: its exit code and what it printed."""

from __future__ import annotations

import sys

import pytest


def run_main(monkeypatch, capsys, *args) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``toddlerbot ARGS`` through `toddlerbot.cli.main.main`, which turns every
    error into one line on stderr."""
    from toddlerbot.cli.main import main

    monkeypatch.setattr(sys, "argv", ["toddlerbot", *map(str, args)])
    with pytest.raises(SystemExit) as info:
        main()
    out = capsys.readouterr()
    return info.value.code, out.out, out.err


def one_line_error(code: int, err: str) -> str:
    """The one error line of a refused command (exit code 2, no traceback)."""
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("error: "), lines[0]
    return lines[0]
