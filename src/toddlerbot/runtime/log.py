"""Run logs: one row per control step, saved as a compressed ``.npz``. A run with a log file writes its rows to
disk in chunks while it goes on (`LogRecorder`), so that a long run holds a bounded number of rows and a killed one
leaves every complete chunk, which `RunLog.load` reads.

Keys (n = control steps, m = motors; arrays follow `toddlerbot.robot.interface.Observation` units and frames):

==================  ==========  ====================================================================
time                (n,)        s since reset (observation time at the start of the step)
command             (n, 3)      vx m/s, vy m/s, yaw rate rad/s given to the policy
motor_pos/vel       (n, m)      observed motor angles rad, speeds rad/s
motor_torque        (n, m)      motor torque N*m (simulated or estimated)
joint_pos/vel       (n, m)      observed output-joint positions/speeds
motor_target        (n, m)      commanded motor targets rad (before the backend's limit clamp)
joint_target        (n, m)      the same targets in joint space
imu_quat            (n, 4)      torso orientation w, x, y, z
imu_ang_vel         (n, 3)      rad/s, IMU frame
imu_lin_acc         (n, 3)      m/s^2, IMU frame
foot_contact        (n, 2)      left, right
base_pos            (n, 3)      torso position in the world, m (simulation ground truth; NaN on hardware)
base_quat           (n, 4)      torso orientation in the world (simulation ground truth; NaN on hardware)
compute_time        (n,)        s spent in policy + backend step
step_period         (n,)        s of wall time from this step's start to the next's
motor_kp/kd         (n, m)      firmware gains in effect during the step (optional: absent in older logs)
recovering          (n,)        1 where the recovery policy (``--on-fall get-up``) drove the step (optional: only
                                in runs with one)
motor_names         (m,)        str
joint_names         (m,)        str
control_dt          ()          s
policy              ()          str
==================  ==========  ====================================================================
"""

from __future__ import annotations

import contextlib
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_savez

STEP_KEYS = (
    "time", "command", "motor_pos", "motor_vel", "motor_torque", "joint_pos", "joint_vel", "motor_target",
    "joint_target", "imu_quat", "imu_ang_vel", "imu_lin_acc", "foot_contact", "base_pos", "base_quat",
    "compute_time", "step_period",
)
MAX_RUN_LOG_BYTES = 1 << 30
"""Largest run log (uncompressed), bytes: a compressed .npz of a few kB could otherwise expand to gigabytes."""
OPTIONAL_STEP_KEYS = ("motor_kp", "motor_kd", "recovering")
"""Recorded when given to `LogRecorder.append`; logs written before they existed load with None."""
HEADER_KEYS = ("motor_names", "joint_names", "control_dt", "policy")
"""What names the run (every chunk of one run carries the same)."""
CHUNK_SECONDS = 10.0
"""Control time a recorder with a log file holds before writing it to a chunk, s (500 rows at 50 Hz, 1.2 MB)."""


def parts_of(path: str | Path) -> Path:
    """The folder where the recorder of the log file `path` writes its chunks while the run goes on: ``x.npz.parts``
    beside ``x.npz``."""
    path = Path(path)
    return path.with_name(f"{path.name}.parts")


def _chunks(folder: Path) -> list[Path]:
    """The complete chunks in `folder`, in order (a chunk being written is a temporary file starting with '.')."""
    return sorted(folder.glob("[0-9]*.npz"))


def _expanded_size(path: Path) -> int:
    """Bytes the .npz `path` expands to, read before anything is decompressed."""
    with zipfile.ZipFile(path) as archive:
        return sum(info.file_size for info in archive.infolist())


def _read(path: Path, keys: Sequence[str]) -> dict[str, np.ndarray]:
    """The arrays of the .npz `path` (the optional step keys where present); one line naming the file otherwise."""
    if path.exists() and not path.is_file():  # a device such as /dev/zero would be read forever
        raise ToddlerbotError(f"{path} is not a run log (.npz with the keys of toddlerbot.runtime.log): not a regular "
                              "file")
    try:
        expanded = _expanded_size(path)
        if expanded > MAX_RUN_LOG_BYTES:
            raise ToddlerbotError(f"{path}: expands to {expanded} bytes; a run log has at most "
                                  f"{MAX_RUN_LOG_BYTES} bytes (an hour at 50 Hz is about 450 MB)")
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in keys if k in data or k not in OPTIONAL_STEP_KEYS}
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        reason = " ".join(str(exc).split()) or f"{type(exc).__name__}: empty or truncated"
        raise ToddlerbotError(f"{path} is not a run log (.npz with the keys of toddlerbot.runtime.log): {reason}") \
            from None


def _concatenate(chunks: list[dict[str, np.ndarray]], where: Path) -> dict[str, np.ndarray]:
    """The arrays of consecutive chunks of one run as one log's (each chunk's step arrays dropped once joined, so
    that the log is not held twice); an optional key only where every chunk has it."""
    first = chunks[0]
    for k, chunk in enumerate(chunks[1:], 1):
        differs = [key for key in HEADER_KEYS if not np.array_equal(chunk[key], first[key])]
        if differs:
            raise ToddlerbotError(f"{where}: chunk {k} differs from chunk 0 in {', '.join(differs)}: chunks of "
                                  "different runs")
    joined = {key: first[key] for key in HEADER_KEYS}
    try:
        for key in (*STEP_KEYS, *OPTIONAL_STEP_KEYS):
            if all(key in chunk for chunk in chunks):
                joined[key] = np.concatenate([chunk.pop(key) for chunk in chunks])
    except ValueError as exc:
        raise ToddlerbotError(f"{where}: chunks do not fit together: {exc}") from None
    return joined


def _remove_chunks(folder: Path) -> None:
    """Remove a recorder's chunks (and a chunk it was writing when killed), then the folder if nothing else is in it."""
    for chunk in folder.glob("*.npz"):
        chunk.unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        folder.rmdir()


def _check_shapes(values: dict, path: Path) -> None:
    """Every per-step array has one row per time step; motor/joint arrays one column per name; time and the
    control period are finite and time increases (NaN elsewhere is allowed: e.g. no ground truth on hardware)."""
    n, motors, joints = len(values["time"]), len(values["motor_names"]), len(values["joint_names"])
    if not np.isfinite(values["control_dt"]) or values["control_dt"] <= 0:
        raise ToddlerbotError(f"{path}: control_dt must be a finite period > 0 s")
    time_ = np.asarray(values["time"], dtype=float) if values["time"].dtype.kind in "fiu" else None
    if time_ is None or time_.ndim != 1 or not np.all(np.isfinite(time_)) or np.any(np.diff(time_) < 0):
        raise ToddlerbotError(f"{path}: 'time' must be finite and non-decreasing")
    widths = {"motor_pos": motors, "motor_vel": motors, "motor_torque": motors, "motor_target": motors,
              "joint_pos": joints, "joint_vel": joints, "joint_target": joints}
    for name in STEP_KEYS:
        array = values[name]
        if array.dtype.kind not in "fiub" or len(array) != n or (name in widths and array.shape[1:] != (widths[name],)):
            raise ToddlerbotError(f"{path}: '{name}' has shape {array.shape} ({array.dtype}); expected {n} rows"
                                  + (f" of {widths[name]}" if name in widths else ""))


@dataclass(frozen=True)
class RunLog:
    time: np.ndarray
    command: np.ndarray
    motor_pos: np.ndarray
    motor_vel: np.ndarray
    motor_torque: np.ndarray
    joint_pos: np.ndarray
    joint_vel: np.ndarray
    motor_target: np.ndarray
    joint_target: np.ndarray
    imu_quat: np.ndarray
    imu_ang_vel: np.ndarray
    imu_lin_acc: np.ndarray
    foot_contact: np.ndarray
    base_pos: np.ndarray
    base_quat: np.ndarray
    compute_time: np.ndarray
    step_period: np.ndarray
    motor_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    control_dt: float
    policy: str
    motor_kp: np.ndarray | None = None
    """(n, m) firmware P gains in effect at each step (None: not recorded)."""
    motor_kd: np.ndarray | None = None
    recovering: np.ndarray | None = None
    """(n,) 1 where the recovery policy drove the step (None: the run had none)."""

    def save(self, path: str | Path) -> Path:
        """Write the log as a compressed ``.npz`` atomically (concurrent saves of one path never mix), then remove
        the chunks a recorder left for that file (`parts_of`): the file holds the log now."""
        path = atomic_savez(path, self._arrays(), compressed=True)
        _remove_chunks(parts_of(path))
        return path

    def _arrays(self) -> dict[str, np.ndarray]:
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self) if getattr(self, f.name) is not None}

    @classmethod
    def load(cls, path: str | Path) -> RunLog:
        """The log in `path`, or the chunks of a run killed before it saved its log (every complete chunk): those in
        the folder `path`, or in `parts_of(path)` when the file `path` does not exist. One line naming the file for
        anything else (not an .npz, expanding to more than `MAX_RUN_LOG_BYTES`, inconsistent shapes, chunks of
        different runs)."""
        path = Path(path)
        keys = [f.name for f in fields(cls)]
        folder = path if path.is_dir() else parts_of(path) if not path.exists() else None
        if folder is None or not folder.is_dir():
            return cls._of(_read(path, keys), path)
        files = _chunks(folder)
        if not files:
            raise ToddlerbotError(f"{folder}: holds no chunk of a run log (numbered .npz files)")
        expanded = sum(_expanded_size(f) for f in files)
        if expanded > MAX_RUN_LOG_BYTES:
            raise ToddlerbotError(f"{folder}: its chunks expand to {expanded} bytes; a run log has at most "
                                  f"{MAX_RUN_LOG_BYTES} bytes")
        return cls._of(_concatenate([_read(f, keys) for f in files], folder), folder)

    @classmethod
    def _of(cls, values: dict[str, np.ndarray], path: Path) -> RunLog:
        """The log of the arrays read from `path`, once their shapes are checked."""
        values["motor_names"] = tuple(str(s) for s in values["motor_names"].reshape(-1))
        values["joint_names"] = tuple(str(s) for s in values["joint_names"].reshape(-1))
        values["control_dt"] = float(values["control_dt"]) if values["control_dt"].size == 1 else float("nan")
        values["policy"] = str(values["policy"])
        _check_shapes(values, path)
        return cls(**values)


class LogRecorder:
    """Collects one row per step; `finish` stacks them into a `RunLog`.

    Given the log's file (`path`), once `start` has named the run, the recorder writes the rows it holds to the
    next numbered chunk in `parts_of(path)` every `chunk_seconds` of control time (an uncompressed .npz run log:
    10 s of 30 motors in 5 ms, 9 ms in a HIL walk on a loaded 2-core VM, inside a 20 ms control period, where
    compressing takes 30 ms), so it holds at most that many rows and a killed run leaves every complete chunk.
    `finish` joins the chunks and the rows held; the chunks stay on disk until `RunLog.save(path)` has the whole log
    in the file. A chunk that cannot be written (a full disk) ends the spilling: the rows stay in memory as without
    a file, and the run goes on."""

    def __init__(self, path: str | Path | None = None, chunk_seconds: float = CHUNK_SECONDS) -> None:
        self.parts = None if path is None else parts_of(path)
        if self.parts is not None and _chunks(self.parts):
            raise ToddlerbotError(f"{self.parts} holds the chunks of an unfinished run logged to {path}: keep them "
                                  "as a log (docs/hardware.md, \"Run logs in chunks\") or remove the folder first")
        self.chunk_seconds = chunk_seconds
        self.rows: dict[str, list[np.ndarray]] = {k: [] for k in (*STEP_KEYS, *OPTIONAL_STEP_KEYS)}
        self.chunks: list[Path] = []
        """The chunks written so far."""
        self.spilled = 0
        """Rows written to chunks (no longer held)."""
        self._header: dict | None = None
        self._chunk_rows = 0

    def __len__(self) -> int:
        """Steps recorded so far (in chunks and held)."""
        return self.spilled + len(self.rows["time"])

    def start(self, motor_names, joint_names, control_dt: float, policy: str) -> None:
        """Name the run (every chunk carries its names); with a log file, rows go to chunks from now on."""
        self._header = {"motor_names": tuple(motor_names), "joint_names": tuple(joint_names),
                        "control_dt": control_dt, "policy": policy}
        self._chunk_rows = max(1, round(self.chunk_seconds / control_dt))

    def append(self, **row: np.ndarray | float) -> None:
        for key in (*STEP_KEYS, *(k for k in OPTIONAL_STEP_KEYS if k in row)):
            self.rows[key].append(np.asarray(row[key], dtype=float))
        if self.parts is not None and self._header is not None and len(self.rows["time"]) >= self._chunk_rows:
            self._spill()

    def _spill(self) -> None:
        chunk = self.parts / f"{len(self.chunks):06d}.npz"
        try:
            self.parts.mkdir(exist_ok=True)
            atomic_savez(chunk, self._stack(**self._header)._arrays())
        except OSError:
            self.parts = None  # the rows stay held; saving the whole log at the end reports a full disk
            return
        self.chunks.append(chunk)
        self.spilled += len(self.rows["time"])
        for rows in self.rows.values():
            rows.clear()

    def finish(self, motor_names, joint_names, control_dt: float, policy: str) -> RunLog:
        """The whole log: the chunks written so far, then the rows held."""
        held = self._stack(motor_names, joint_names, control_dt, policy)
        if not self.chunks:
            return held
        keys = [f.name for f in fields(RunLog)]
        pieces = [_read(chunk, keys) for chunk in self.chunks] + ([held._arrays()] if held.time.size else [])
        return RunLog._of(_concatenate(pieces, self.chunks[0].parent), self.chunks[0].parent)

    def _stack(self, motor_names, joint_names, control_dt: float, policy: str) -> RunLog:
        n = len(self.rows["time"])
        return RunLog(
            **{k: np.array(v) if k in STEP_KEYS or len(v) == n else None for k, v in self.rows.items()},
            motor_names=tuple(motor_names), joint_names=tuple(joint_names), control_dt=control_dt, policy=policy,
        )
