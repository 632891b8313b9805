"""Run logs: one row per control step, saved as a compressed ``.npz``.

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
motor_names         (m,)        str
joint_names         (m,)        str
control_dt          ()          s
policy              ()          str
==================  ==========  ====================================================================
"""

from __future__ import annotations

import zipfile
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
OPTIONAL_STEP_KEYS = ("motor_kp", "motor_kd")
"""Recorded when given to `LogRecorder.append`; logs written before they existed load with None."""


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

    def save(self, path: str | Path) -> Path:
        """Write the log as a compressed ``.npz`` atomically (concurrent saves of one path never mix)."""
        arrays = {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)
                  if getattr(self, f.name) is not None}
        return atomic_savez(path, arrays, compressed=True)

    @classmethod
    def load(cls, path: str | Path) -> RunLog:
        """The log in `path`; one line naming the file for anything else (not an .npz, expanding to more than
        `MAX_RUN_LOG_BYTES`, inconsistent shapes)."""
        path = Path(path)
        try:
            with zipfile.ZipFile(path) as archive:  # checked before np.load decompresses anything
                expanded = sum(info.file_size for info in archive.infolist())
            if expanded > MAX_RUN_LOG_BYTES:
                raise ToddlerbotError(f"{path}: expands to {expanded} bytes; a run log has at most "
                                      f"{MAX_RUN_LOG_BYTES} bytes (an hour at 50 Hz is about 450 MB)")
            with np.load(path, allow_pickle=False) as data:
                values = {f.name: data[f.name] for f in fields(cls) if f.name in data or f.name not in
                          OPTIONAL_STEP_KEYS}
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            reason = " ".join(str(exc).split()) or f"{type(exc).__name__}: empty or truncated"
            raise ToddlerbotError(f"{path} is not a run log (.npz with the keys of toddlerbot.runtime.log): {reason}") \
                from None
        values["motor_names"] = tuple(str(s) for s in values["motor_names"].reshape(-1))
        values["joint_names"] = tuple(str(s) for s in values["joint_names"].reshape(-1))
        values["control_dt"] = float(values["control_dt"]) if values["control_dt"].size == 1 else float("nan")
        values["policy"] = str(values["policy"])
        _check_shapes(values, path)
        return cls(**values)


class LogRecorder:
    """Collects one row per step; `finish` stacks them into a `RunLog`."""

    def __init__(self) -> None:
        self.rows: dict[str, list[np.ndarray]] = {k: [] for k in (*STEP_KEYS, *OPTIONAL_STEP_KEYS)}

    def __len__(self) -> int:
        """Steps recorded so far."""
        return len(self.rows["time"])

    def append(self, **row: np.ndarray | float) -> None:
        for key in (*STEP_KEYS, *(k for k in OPTIONAL_STEP_KEYS if k in row)):
            self.rows[key].append(np.asarray(row[key], dtype=float))

    def finish(self, motor_names, joint_names, control_dt: float, policy: str) -> RunLog:
        n = len(self.rows["time"])
        return RunLog(
            **{k: np.array(v) if k in STEP_KEYS or len(v) == n else None for k, v in self.rows.items()},
            motor_names=tuple(motor_names), joint_names=tuple(joint_names), control_dt=control_dt, policy=policy,
        )
