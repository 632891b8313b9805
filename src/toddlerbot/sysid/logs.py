"""Run logs: one CSV per run, columns ``time`` (s), ``goal_position`` (rad), ``position`` (rad), optionally
``velocity`` (rad/s) and ``current`` (A); extra columns are ignored. Positions are motor-shaft angles."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.files import atomic_write_text
from toddlerbot.sysid.errors import SysIDError

REQUIRED_COLUMNS = ("time", "goal_position", "position")
OPTIONAL_COLUMNS = ("velocity", "current")


@dataclass(frozen=True)
class MotorLog:
    """One logged run of a motor on a sysID rig at fixed firmware gains."""

    file: Path
    time: np.ndarray
    """Sample times, s, strictly increasing."""
    goal_position: np.ndarray
    """Commanded motor position, rad (held until the next sample)."""
    position: np.ndarray
    """Measured motor position, rad."""
    kp: float
    """Dynamixel firmware position P gain of the run."""
    kd: float
    """Dynamixel firmware position D gain of the run."""
    velocity: np.ndarray | None = None
    """Measured velocity, rad/s."""
    current: np.ndarray | None = None
    """Measured current, A."""

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    @property
    def initial_velocity(self) -> float:
        """Logged velocity at the first sample, rad/s (0 when the log has no velocity column)."""
        return 0.0 if self.velocity is None else float(self.velocity[0])


def read_columns(path: str | Path, required: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Numeric CSV columns by header name (at least 2 rows, all finite); raise `SysIDError` naming the file,
    line and column at fault."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SysIDError(f"{path}: cannot read log ({exc.strerror or exc})") from None
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise SysIDError(f"{path}: empty log; expected a header row with columns {', '.join(required)}")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in required if c not in header]
    if missing:
        raise SysIDError(f"{path}: missing column(s) {', '.join(missing)}; header is {', '.join(header)}")
    wanted = {c: header.index(c) for c in (*required, *optional) if c in header}
    columns: dict[str, list[float]] = {c: [] for c in wanted}
    for line, row in enumerate(rows[1:], start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        for c, i in wanted.items():
            try:
                columns[c].append(float(row[i]))
            except (IndexError, ValueError):
                cell = row[i] if i < len(row) else "<missing>"
                raise SysIDError(f"{path}: line {line}: column {c!r} is not a number ({cell!r})") from None
    data = {c: np.asarray(v, dtype=float) for c, v in columns.items()}
    n = len(data[required[0]])
    if n < 2:
        raise SysIDError(f"{path}: needs at least 2 samples, found {n}")
    for c, values in data.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise SysIDError(f"{path}: column {c!r} has NaN/inf at data row {bad[0] + 1} ({bad.size} value(s))")
    if "time" in data:
        steps = np.diff(data["time"])
        if np.any(steps <= 0):
            row = int(np.flatnonzero(steps <= 0)[0]) + 2
            raise SysIDError(f"{path}: time is not strictly increasing at data row {row}")
    return data


def read_log(path: str | Path, kp: float, kd: float) -> MotorLog:
    """Read and validate one run CSV; raise `SysIDError` naming the file and the problem."""
    data = read_columns(path, REQUIRED_COLUMNS, OPTIONAL_COLUMNS)
    if not (np.isfinite(kp) and kp >= 0 and np.isfinite(kd) and kd >= 0):
        raise SysIDError(f"{path}: firmware gains must be finite and >= 0, got kp={kp}, kd={kd}")
    return MotorLog(
        file=Path(path), time=data["time"], goal_position=data["goal_position"], position=data["position"],
        kp=float(kp), kd=float(kd), velocity=data.get("velocity"), current=data.get("current"),
    )


def format_log(time: np.ndarray, goal_position: np.ndarray, position: np.ndarray | None = None,
               velocity: np.ndarray | None = None) -> str:
    """CSV text of a run (``position`` omitted for an excitation profile that has not been run yet)."""
    columns = {"time": time, "goal_position": goal_position, "position": position, "velocity": velocity}
    columns = {k: np.asarray(v, dtype=float) for k, v in columns.items() if v is not None}
    lines = [",".join(columns)]
    lines += [",".join(f"{x:.9g}" for x in row) for row in zip(*columns.values(), strict=True)]
    return "\n".join(lines) + "\n"


def write_log(path: str | Path, time: np.ndarray, goal_position: np.ndarray, position: np.ndarray | None = None,
              velocity: np.ndarray | None = None) -> Path:
    """Write a run CSV atomically."""
    return atomic_write_text(path, format_log(time, goal_position, position, velocity))
