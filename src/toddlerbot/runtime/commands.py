"""Velocity-command sources. A scripted schedule is a list of ``time: vx,vy,yaw_rate`` entries separated by ``;``
or newlines (``#`` starts a comment), e.g. ``"0:0.1,0,0; 5:0,0,0.3"``: from each time on (s) the command holds
(vx m/s, vy m/s, yaw rate rad/s) in the robot frame until the next entry."""

from __future__ import annotations

import itertools
from bisect import bisect_right
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.yaml_input import read_text

MAX_COMMAND_FILE_BYTES = 1_000_000
"""Size cap of a command file, bytes (a schedule of one entry per second for a day is about 400 kB)."""


class CommandError(ToddlerbotError):
    """A command string or command file is malformed."""


class CommandSchedule:
    """Piecewise-constant velocity commands over time; call it with t (s) to get (vx, vy, yaw_rate)."""

    def __init__(self, times: list[float], commands: list[np.ndarray]) -> None:
        if not times:
            raise CommandError("a command schedule needs at least one entry")
        if any(b <= a for a, b in itertools.pairwise(times)):
            raise CommandError(f"command times must increase, got {times}")
        self.times = list(times)
        self.commands = [np.asarray(c, dtype=float) for c in commands]

    def __call__(self, t: float) -> np.ndarray:
        i = bisect_right(self.times, t) - 1
        return np.zeros(3) if i < 0 else self.commands[i]

    @classmethod
    def parse(cls, text: str, source: str = "--command") -> CommandSchedule:
        times, commands = [], []
        expected = "expected 'time: vx,vy,yaw_rate' like '0:0.1,0,0'"
        entries = [e.split("#", 1)[0].strip() for line in text.splitlines() for e in line.split(";")]
        for entry in filter(None, entries):
            if ":" not in entry:
                raise CommandError(f"{source}: malformed command {entry!r}; {expected}")
            t_text, values_text = entry.split(":", 1)
            try:
                t = float(t_text)
                values = [float(v) for v in values_text.split(",")]
            except ValueError:
                raise CommandError(f"{source}: malformed command {entry!r}; {expected}") from None
            if len(values) != 3 or not np.all(np.isfinite([t, *values])) or t < 0:
                raise CommandError(f"{source}: malformed command {entry!r}; {expected} with time >= 0")
            times.append(t)
            commands.append(np.array(values))
        if not times:
            raise CommandError(f"{source}: no commands given; {expected}")
        return cls(times, commands)

    @classmethod
    def from_file(cls, path: str | Path) -> CommandSchedule:
        """The schedule in a text file (UTF-8, at most `MAX_COMMAND_FILE_BYTES`; /dev/zero is refused, not read)."""
        text = read_text(path, "command file", CommandError, MAX_COMMAND_FILE_BYTES)
        return cls.parse(text, source=str(path))
