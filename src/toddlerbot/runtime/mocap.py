"""Table 7 from a run log (`eval tracking --log`): the tracking errors of `toddlerbot.runtime.tracking` computed on
a logged run, with the log's own ground-truth pose (`sim run --log`, `hw run --mocap emulator --log`) or with an
external motion capture aligned to the log's clock (`--mocap FILE.csv`).

The capture file is one CSV layout (docs/hardware.md, "Table 7 on the real robot"): a header naming the columns
``time,x,y,z,qw,qx,qy,qz`` (any order, other columns ignored) and one row per frame: time in s, the torso's
position in m and its orientation as a unit quaternion, scalar first, in a world frame with z up. A row whose seven
pose cells are all empty is a frame the system lost (the way Motive exports one).

Clocks: the capture's clock and the log's (s since the run's reset) differ by an unknown offset. It is found by
cross-correlating two measurements of the same yaw rate: the capture's (the z component of the world-frame angular
velocity from consecutive quaternions) and the log's IMU gyro rotated into the world by the IMU's orientation, z
component. The world-frame z rate, not the body z rate, because it does not depend on how the capture's rigid body
was placed on the torso (a body-frame rate would, and the capture's body axes are the lab's choice) nor on the
IMU's yaw origin (the BNO08x's game rotation vector has an arbitrary one), and the torso's sway during a gait cycle
does not leak into it. Both rates are low-pass filtered without phase shift, sampled on the capture's rate, and the
normalised correlation is searched over every offset at which the two overlap by at least `MIN_OVERLAP` of the log,
then refined between samples by a parabola through the peak.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.spatial.transform import Rotation, Slerp

from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware.imu import REPORT_INTERVAL_S
from toddlerbot.hardware.imu_stream import LATENCY_S
from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.robot.fall import FALL_TILT_RAD, tilt
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.tracking import TrackingResult, tracking_errors
from toddlerbot.yaml_input import read_text

COLUMNS = ("time", "x", "y", "z", "qw", "qx", "qy", "qz")
"""The capture file's columns: s, m, m, m, unit quaternion scalar first; world z up."""
MAX_CAPTURE_BYTES = 128 << 20
"""Largest capture file read: an hour at 240 Hz, rows of about 100 characters, is 86 MB."""
MAX_POSITION_M = 100.0
"""A coordinate beyond this is not metres (an export in millimetres)."""
UNIT_TOLERANCE = 0.01
"""How far a quaternion's norm may be from 1 (an export rounds to 4-6 decimals)."""
MAX_GAP_S = 0.1
"""Longest stretch without a frame inside the evaluated span that is interpolated over (5 control steps; the
velocity errors average over a 0.6 s gait cycle); a longer one is refused."""
MIN_CORRELATION = 0.7
"""Smallest normalised correlation of the two yaw rates accepted as an alignment."""
DISTINCT_MARGIN = 0.05
"""The best offset must beat every offset more than half a gait cycle away by this much of correlation; a walk
that never turns repeats each gait cycle's yaw sway, and the capture would match it one cycle early or late."""
MIN_OVERLAP = 0.5
"""Fraction of the log's span that the capture must overlap at an offset for the offset to be searched; what is
not covered at the best offset is then reported as such (`capture_pose_at`)."""
SMOOTHING_HZ = 5.0
"""Cut-off of the zero-phase low-pass applied to both yaw rates (the gait's yaw sway is at 1.7 Hz, one 0.6 s cycle)."""
MIN_YAW_RATE = 0.02
"""A yaw rate whose standard deviation stays under this, rad/s, holds nothing to align on."""
IMU_AGE_S = LATENCY_S + REPORT_INTERVAL_S / 2
"""Mean age of the IMU reading in an observation, s: the BNO08x reports every 10 ms, each about 5 ms old
(`toddlerbot.hardware.imu_stream.LATENCY_S`). The correlation lines the capture up with the gyro, so the offset is
moved by this much to line it up with the observation's time. The HIL emulator's IMU lags its own pose by 12-15 ms
on a 2-core VM at load 6-12, and lagged by 21 ms in a run where its 10 ms ticks slipped (load 12): its reports are
samples taken at those ticks, which a busy host delays."""


@dataclass(frozen=True)
class Capture:
    """A motion capture of the torso: frame times (s, the capture's clock), positions (m) and unit quaternions
    (w, x, y, z), world z up."""

    time: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    source: str


@dataclass(frozen=True)
class Alignment:
    offset_s: float
    """Capture time minus log time, s."""
    correlation: float
    """Normalised correlation of the two yaw rates at that offset (1: the same shape)."""


def read_capture(path: str | Path) -> Capture:
    """The capture in the CSV file `path` (module docstring); one line naming the file, line and field for
    anything malformed."""
    path = Path(path)
    text = read_text(path, "motion-capture file", max_bytes=MAX_CAPTURE_BYTES, kind="a CSV file").lstrip("\ufeff")
    reader = csv.reader(io.StringIO(text))
    header = [name.strip().lower() for name in next(reader, [])]
    missing = [name for name in COLUMNS if name not in header]
    if missing:
        raise ToddlerbotError(f"{path} line 1: missing column {', '.join(map(repr, missing))}; expected the header "
                              f"{','.join(COLUMNS)} (docs/hardware.md, \"Table 7 on the real robot\")")
    index = [header.index(name) for name in COLUMNS]
    rows: list[list[float]] = []
    for cells in reader:
        if not any(cell.strip() for cell in cells):
            continue  # a blank line
        line = reader.line_num
        if len(cells) < len(header):
            raise ToddlerbotError(f"{path} line {line}: {len(cells)} fields, the header has {len(header)}")
        values = [cells[i].strip() for i in index]
        if values[0] and not any(values[1:]):
            continue  # a frame the system lost: a gap
        rows.append([_number(path, line, name, value) for name, value in zip(COLUMNS, values, strict=True)])
        _check_row(path, line, rows)
    if len(rows) < 2:
        raise ToddlerbotError(f"{path}: {len(rows)} frames; a capture needs at least 2")
    data = np.array(rows)
    quat = data[:, 4:8] / np.linalg.norm(data[:, 4:8], axis=1, keepdims=True)
    return Capture(time=data[:, 0], pos=data[:, 1:4], quat=quat, source=str(path))


def _number(path: Path, line: int, name: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ToddlerbotError(f"{path} line {line}, field {name}: {text[:30]!r} is not a finite number")
    return value


def _check_row(path: Path, line: int, rows: list[list[float]]) -> None:
    """The row just read: time after the previous row's, position in metres, a unit quaternion."""
    row = rows[-1]
    if len(rows) > 1 and row[0] <= rows[-2][0]:
        raise ToddlerbotError(f"{path} line {line}, field time: {row[0]:g} s is not after the previous frame's "
                              f"{rows[-2][0]:g} s (frames must be in time order, without repeats)")
    for name, value in zip(COLUMNS[1:4], row[1:4], strict=True):
        if abs(value) > MAX_POSITION_M:
            raise ToddlerbotError(f"{path} line {line}, field {name}: {value:g} is more than {MAX_POSITION_M:g} m "
                                  "from the origin; positions are in metres (divide an export in mm by 1000)")
    norm = math.sqrt(sum(v * v for v in row[4:8]))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise ToddlerbotError(f"{path} line {line}, fields qw,qx,qy,qz: norm {norm:.4g}, not a unit quaternion "
                              f"(|norm - 1| <= {UNIT_TOLERANCE:g}; scalar first: qw,qx,qy,qz)")


def imu_yaw_rate(log: RunLog) -> np.ndarray:
    """(n,) the log's IMU gyro rotated into the world by the IMU's orientation: its z component, rad/s."""
    return Rotation.from_quat(log.imu_quat, scalar_first=True).apply(log.imu_ang_vel)[:, 2]


def capture_yaw_rate(capture: Capture) -> tuple[np.ndarray, np.ndarray]:
    """(times, rates): the world-frame z angular velocity between consecutive frames, rad/s, at their midpoints."""
    rotations = Rotation.from_quat(capture.quat, scalar_first=True)
    dt = np.diff(capture.time)
    rates = (rotations[1:] * rotations[:-1].inv()).as_rotvec()[:, 2] / dt
    return capture.time[:-1] + dt / 2, rates


def align_capture(log: RunLog, capture: Capture, log_name: str, imu_age_s: float = IMU_AGE_S) -> Alignment:
    """The offset between the capture's clock and the log's (module docstring); one line when the yaw rates do not
    match well enough or hold nothing to match."""
    gyro = imu_yaw_rate(log)
    if not np.all(np.isfinite(gyro)):
        raise ToddlerbotError(f"{log_name}: the IMU readings are not finite; the capture is aligned on the gyro")
    if np.std(gyro) < MIN_YAW_RATE:
        raise ToddlerbotError(f"{log_name}: the IMU's yaw rate varies by {np.std(gyro):.3f} rad/s (standard "
                              f"deviation), under {MIN_YAW_RATE} rad/s: nothing to align the capture on (a run "
                              "with --imu none, or one that never turned)")
    rate_hz = 1.0 / float(np.median(np.diff(capture.time)))
    step = 1.0 / rate_hz
    log_t = np.arange(log.time[0], log.time[-1], step)
    ours = _smooth(np.interp(log_t, log.time, gyro), rate_hz)
    mid, rates = capture_yaw_rate(capture)
    cap_t = np.arange(mid[0], mid[-1], step)
    theirs = _smooth(np.interp(cap_t, mid, rates), rate_hz)
    lags, corr = _normalised_correlation(theirs, ours, min_overlap=round(MIN_OVERLAP * len(ours)))
    if corr.size == 0:
        raise ToddlerbotError(f"{capture.source}: its {cap_t[-1] - cap_t[0]:.1f} s cannot overlap half of the "
                              f"{log.time[-1] - log.time[0]:.1f} s run in {log_name}")
    best = int(np.argmax(corr))
    offset = cap_t[0] - log_t[0] + (lags[best] + _parabola_peak(corr, best)) * step
    if corr[best] < MIN_CORRELATION:
        raise ToddlerbotError(
            f"{capture.source}: its yaw rate matches the IMU gyro of {log_name} at best with correlation "
            f"{corr[best]:.2f} (offset {offset:+.2f} s), under {MIN_CORRELATION}: not a capture of this run, a "
            "rigid body that is not the torso, or axes not converted to z up")
    far = np.abs(lags - lags[best]) * step > WalkConfig.cycle_time / 2
    if far.any() and corr[far].max() > corr[best] - DISTINCT_MARGIN:
        other = cap_t[0] - log_t[0] + lags[far][np.argmax(corr[far])] * step
        raise ToddlerbotError(
            f"{capture.source}: offsets {offset:+.2f} s and {other:+.2f} s match the IMU gyro of {log_name} almost "
            f"equally (correlation {corr[best]:.2f} and {corr[far].max():.2f}): the run needs a turn to align on")
    return Alignment(offset_s=float(offset + imu_age_s), correlation=float(corr[best]))


def _smooth(x: np.ndarray, rate_hz: float) -> np.ndarray:
    """Zero-phase low-pass (4th-order Butterworth at `SMOOTHING_HZ`), so the filter moves no peak in time."""
    sos = signal.butter(4, min(SMOOTHING_HZ, 0.4 * rate_hz), fs=rate_hz, output="sos")
    return signal.sosfiltfilt(sos, x) if len(x) > 30 else x


def _normalised_correlation(b: np.ndarray, a: np.ndarray, min_overlap: int) -> tuple[np.ndarray, np.ndarray]:
    """(lags k, correlation): sum a[n] b[n + k] over the samples both have, divided by both signals' norms over
    those samples, for every k at which they overlap by at least `min_overlap` samples."""
    corr = signal.correlate(b, a, mode="full")
    lags = signal.correlation_lags(len(b), len(a), mode="full")
    start = np.maximum(0, -lags)
    end = np.minimum(len(a), len(b) - lags)
    keep = end - start >= max(min_overlap, 1)
    lags, start, end, corr = lags[keep], start[keep], end[keep], corr[keep]
    ea = np.concatenate([[0.0], np.cumsum(a * a)])
    eb = np.concatenate([[0.0], np.cumsum(b * b)])
    energy = (ea[end] - ea[start]) * (eb[end + lags] - eb[start + lags])
    return lags, corr / np.sqrt(np.maximum(energy, 1e-12))


def _parabola_peak(y: np.ndarray, i: int) -> float:
    """Where, between -0.5 and 0.5 samples from `i`, a parabola through y[i-1:i+2] peaks."""
    if i == 0 or i == len(y) - 1:
        return 0.0
    curvature = y[i - 1] - 2 * y[i] + y[i + 1]
    return float(np.clip(0.5 * (y[i - 1] - y[i + 1]) / curvature, -0.5, 0.5)) if curvature < 0 else 0.0


def capture_pose_at(capture: Capture, times: np.ndarray, offset_s: float, log_name: str
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The captured position and orientation (w, x, y, z) at the log's `times` (capture time = log time +
    `offset_s`): linear and spherical-linear interpolation between frames; one line when the capture does not cover
    the times or has a gap longer than `MAX_GAP_S` among them."""
    at = np.asarray(times) + offset_s
    t = capture.time
    if at[0] < t[0] or at[-1] > t[-1]:
        raise ToddlerbotError(
            f"{capture.source} covers log time {t[0] - offset_s:.2f}-{t[-1] - offset_s:.2f} s (offset "
            f"{offset_s:+.3f} s), the run in {log_name} spans {times[0]:.2f}-{times[-1]:.2f} s: record from "
            "before the run starts until after it ends")
    inside = np.flatnonzero((t[1:] > at[0]) & (t[:-1] < at[-1]))
    gaps = inside[np.diff(t)[inside] > MAX_GAP_S]
    if gaps.size:
        i = gaps[0]
        raise ToddlerbotError(
            f"{capture.source}: no frame for {t[i + 1] - t[i]:.2f} s after capture time {t[i]:.3f} s (log time "
            f"{t[i] - offset_s:.2f} s) inside the run ({gaps.size} such gap(s)); gaps up to {MAX_GAP_S:g} s are "
            "interpolated")
    pos = np.stack([np.interp(at, t, capture.pos[:, k]) for k in range(3)], axis=1)
    quat = Slerp(t, Rotation.from_quat(capture.quat, scalar_first=True))(at).as_quat(scalar_first=True)
    return pos, quat


def log_falls(log: RunLog) -> int:
    """Falls in a logged run: one per stretch the recovery policy drove, and one more when the run ended falling.
    The runner stops on the observation after the last logged one, where the IMU's tilt passed `FALL_TILT_RAD`, so
    the last logged tilt is a little short of it (0.89-0.99 rad in four HIL falls); a walking torso stays within
    0.2 rad. So: tilted beyond half the fall tilt at the last step, outside a recovery."""
    recovering = np.zeros(len(log.time), bool) if log.recovering is None else np.asarray(log.recovering, bool)
    stretches = int(np.count_nonzero(np.diff(np.concatenate([[0], recovering.astype(int)])) > 0))
    last = np.asarray(log.imu_quat[-1], float)
    fell_at_end = bool(np.all(np.isfinite(last)) and tilt(last) > FALL_TILT_RAD / 2 and not recovering[-1])
    return stretches + int(fell_at_end)


def log_tracking(log: RunLog, log_name: str, capture: Capture | None = None
                 ) -> tuple[TrackingResult, Alignment | None]:
    """The tracking errors of a logged run, from its own ground-truth pose or, given `capture`, from the capture
    aligned to the log's clock (with the alignment)."""
    if len(log.time) < 2:
        raise ToddlerbotError(f"{log_name}: {len(log.time)} steps; tracking errors need a run of at least 2")
    alignment = None
    if capture is None:
        finite = np.isfinite(log.base_pos).all(axis=1) & np.isfinite(log.base_quat).all(axis=1)
        if not finite.any():
            raise ToddlerbotError(f"{log_name}: no ground-truth pose (a hw run without --mocap logs NaN); give the "
                                  "run's motion capture with --mocap FILE.csv")
        if not finite.all():
            raise ToddlerbotError(f"{log_name}: the ground-truth pose is missing in {np.count_nonzero(~finite)} of "
                                  f"{len(finite)} steps")
        pos, quat = log.base_pos, log.base_quat
    else:
        alignment = align_capture(log, capture, log_name)
        pos, quat = capture_pose_at(capture, log.time, alignment.offset_s, log_name)
    result = tracking_errors(log.time, log.command, pos, quat, fell=False)
    return dataclasses.replace(result, falls=log_falls(log)), alignment
