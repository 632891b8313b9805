"""Run logs: one CSV per run, columns ``time`` (s), ``goal_position`` (rad), ``position`` (rad), optionally
``velocity`` (rad/s), ``current`` (A), ``torque_enable`` (0/1: 0 = the motor was unpowered, passive) and
``voltage`` (V, the supply the motor measured); extra columns are ignored. Positions are motor-shaft angles.

`read_log` refuses, with the file, line and column, what cannot be a servo log in these units: time in ms or
with gaps of minutes (a 1e9 s gap would make the replay allocate terabytes), values beyond any servo's range
(e.g. +-1e300), angles in degrees (more than two turns) or speeds in deg/s or rpm, a torque column other than
0/1, a voltage <= 0.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.files import atomic_write_text
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.yaml_input import read_text

REQUIRED_COLUMNS = ("time", "goal_position", "position")
OPTIONAL_COLUMNS = ("velocity", "current", "torque_enable", "voltage")

STEP_RANGE_S = (2e-4, 0.2)
"""Plausible median sample step of a servo log, s (5 kHz .. 5 Hz); outside it the time is not in seconds."""
MAX_GAP_S = 1.0
"""Longest gap between two samples, s (a servo log is sampled continuously at the bus rate)."""
MAX_DURATION_S = 3600.0
"""Longest run, s."""
MAX_ANGLE_RAD = 4.0 * np.pi
"""Largest |position| / |goal_position|, rad: more than two turns is an angle in degrees (or not an angle)."""
MAX_SPEED = 100.0
"""Largest |velocity|, rad/s (the fastest X-series servo, XL330-M077, runs 40 rad/s unloaded): above is deg/s
or rpm."""
MAX_CURRENT_A = 50.0
"""Largest |current|, A (X-series servos stall at 0.5-5 A): above is mA."""
MAX_LOG_BYTES = 200_000_000
"""Largest log file, bytes: an hour at 200 Hz with every column is about 70 MB."""
VOLTAGE_RANGE_V = (0.0, 30.0)
"""Supply voltage, V: > 0 and at most 30 (X-series servos take 3.7-14.8 V); above is mV."""


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
    torque_enable: np.ndarray | None = None
    """1 where the motor was powered, 0 where torque was off (passive); None: powered throughout."""
    voltage: np.ndarray | None = None
    """Supply voltage at each sample, V; None: the manifest's voltage, else the motor's rated voltage."""

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    @property
    def initial_velocity(self) -> float:
        """Logged velocity at the first sample, rad/s (0 when the log has no velocity column)."""
        return 0.0 if self.velocity is None else float(self.velocity[0])


def read_table(path: str | Path, required: tuple[str, ...], optional: tuple[str, ...] = ()
               ) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """(numeric CSV columns by header name, file line number of each row): at least 2 rows, all finite, time
    strictly increasing; raise `SysIDError` naming the file, line and column at fault."""
    path = Path(path)
    text = read_text(path, "log", SysIDError, MAX_LOG_BYTES, "a CSV text file")
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise SysIDError(f"{path}: empty log; expected a header row with columns {', '.join(required)}")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in required if c not in header]
    if missing:
        raise SysIDError(f"{path}: missing column(s) {', '.join(missing)}; header is {', '.join(header)}")
    wanted = {c: header.index(c) for c in (*required, *optional) if c in header}
    columns: dict[str, list[float]] = {c: [] for c in wanted}
    lines: list[int] = []
    for line, row in enumerate(rows[1:], start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        lines.append(line)
        for c, i in wanted.items():
            try:
                columns[c].append(float(row[i]))
            except (IndexError, ValueError):
                cell = row[i][:40] if i < len(row) else "<missing>"
                raise SysIDError(f"{path}: line {line}: column {c!r} is not a number ({cell!r})") from None
    data = {c: np.asarray(v, dtype=float) for c, v in columns.items()}
    at = np.asarray(lines, dtype=int)
    if len(at) < 2:
        raise SysIDError(f"{path}: needs at least 2 samples, found {len(at)}")
    for c, values in data.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise SysIDError(f"{path}: line {at[bad[0]]}: column {c!r} is NaN/inf ({bad.size} value(s))")
    if "time" in data:
        steps = np.diff(data["time"])
        if np.any(steps <= 0):
            raise SysIDError(f"{path}: line {at[int(np.flatnonzero(steps <= 0)[0]) + 1]}: time is not strictly "
                             f"increasing")
    return data, at


def read_columns(path: str | Path, required: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Numeric CSV columns by header name (see `read_table`)."""
    return read_table(path, required, optional)[0]


def _refuse_outside(path: Path, data: dict[str, np.ndarray], lines: np.ndarray, column: str, bad: np.ndarray,
                    expected: str) -> None:
    if column in data and np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise SysIDError(f"{path}: line {lines[i]}: column {column!r} is {data[column][i]:.6g}; expected {expected}")


def check_servo_log(path: Path, data: dict[str, np.ndarray], lines: np.ndarray) -> None:
    """Refuse a log whose units or values cannot be a servo log's (see the module docstring)."""
    t = data["time"]
    step = float(np.median(np.diff(t)))
    if not STEP_RANGE_S[0] <= step <= STEP_RANGE_S[1]:
        raise SysIDError(f"{path}: column 'time': median sample step {step:.6g} s is not a servo log's "
                         f"({STEP_RANGE_S[0] * 1e3:g} ms to {STEP_RANGE_S[1]:g} s); time must be in seconds"
                         f"{' (this looks like ms)' if step > STEP_RANGE_S[1] else ''}")
    gaps = np.diff(t) > MAX_GAP_S
    if np.any(gaps):
        i = int(np.flatnonzero(gaps)[0]) + 1
        raise SysIDError(f"{path}: line {lines[i]}: column 'time' jumps {t[i] - t[i - 1]:.6g} s; expected samples "
                         f"at most {MAX_GAP_S:g} s apart")
    if t[-1] - t[0] > MAX_DURATION_S:
        raise SysIDError(f"{path}: column 'time' spans {t[-1] - t[0]:.6g} s; expected a run of at most "
                         f"{MAX_DURATION_S:g} s")
    for column in ("position", "goal_position"):
        _refuse_outside(path, data, lines, column, np.abs(data[column]) > MAX_ANGLE_RAD,
                        f"|angle| <= {MAX_ANGLE_RAD:.4g} rad (two turns): angles must be radians, not degrees")
    _refuse_outside(path, data, lines, "velocity", np.abs(data.get("velocity", 0.0)) > MAX_SPEED,
                    f"|speed| <= {MAX_SPEED:g} rad/s: speeds must be rad/s, not deg/s or rpm")
    _refuse_outside(path, data, lines, "current", np.abs(data.get("current", 0.0)) > MAX_CURRENT_A,
                    f"|current| <= {MAX_CURRENT_A:g} A: current must be in A, not mA")
    _refuse_outside(path, data, lines, "torque_enable", ~np.isin(data.get("torque_enable", 0.0), (0.0, 1.0)),
                    "0 (torque off) or 1 (torque on)")
    volts = data.get("voltage", 1.0)
    _refuse_outside(path, data, lines, "voltage", (volts <= VOLTAGE_RANGE_V[0]) | (volts > VOLTAGE_RANGE_V[1]),
                    f"a supply voltage > {VOLTAGE_RANGE_V[0]:g} and <= {VOLTAGE_RANGE_V[1]:g} V")


def read_log(path: str | Path, kp: float, kd: float) -> MotorLog:
    """Read and validate one run CSV; raise `SysIDError` naming the file, line and column at fault."""
    path = Path(path)
    data, lines = read_table(path, REQUIRED_COLUMNS, OPTIONAL_COLUMNS)
    check_servo_log(path, data, lines)
    if not (np.isfinite(kp) and kp >= 0 and np.isfinite(kd) and kd >= 0):
        raise SysIDError(f"{path}: firmware gains must be finite and >= 0, got kp={kp}, kd={kd}")
    return MotorLog(
        file=path, time=data["time"], goal_position=data["goal_position"], position=data["position"],
        kp=float(kp), kd=float(kd), velocity=data.get("velocity"), current=data.get("current"),
        torque_enable=data.get("torque_enable"), voltage=data.get("voltage"),
    )


def format_log(time: np.ndarray, goal_position: np.ndarray, position: np.ndarray | None = None,
               velocity: np.ndarray | None = None, **extra: np.ndarray | None) -> str:
    """CSV text of a run (``position`` omitted for an excitation profile that has not been run yet; ``extra``:
    further columns such as ``current``, ``torque_enable``, ``voltage``; None columns are left out)."""
    columns = {"time": time, "goal_position": goal_position, "position": position, "velocity": velocity, **extra}
    columns = {k: np.asarray(v, dtype=float) for k, v in columns.items() if v is not None}
    lines = [",".join(columns)]
    lines += [",".join(f"{x:.9g}" for x in row) for row in zip(*columns.values(), strict=True)]
    return "\n".join(lines) + "\n"


def write_log(path: str | Path, time: np.ndarray, goal_position: np.ndarray, position: np.ndarray | None = None,
              velocity: np.ndarray | None = None, **extra: np.ndarray | None) -> Path:
    """Write a run CSV atomically."""
    return atomic_write_text(path, format_log(time, goal_position, position, velocity, **extra))
