"""Raw episodes as recorded (50 Hz joints, camera frames with their own timestamps) and their 10 Hz resampling.

A raw episode is kept on disk as one ``.npz`` (no pickle: every array is numeric or a fixed-width string) so it
can be converted again at another rate. `resample` makes the training episode: joints and actions linearly
interpolated at ``k / fps``, the camera frame nearest in time for each sample.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError


class EpisodeError(ToddlerbotError):
    """A raw episode file is missing, truncated or inconsistent."""


@dataclass(frozen=True)
class RawEpisode:
    """One recorded episode. Times in s from the episode start; angles in rad, motor-id order of `names`."""

    task: str
    names: tuple[str, ...]
    """Motor names of the state and action columns."""
    time: np.ndarray
    """(T,) control-step times (50 Hz)."""
    state: np.ndarray
    """(T, D) follower motor angles."""
    action: np.ndarray
    """(T, D) leader (commanded) motor targets."""
    image_time: np.ndarray
    """(M,) camera frame times."""
    images: np.ndarray
    """(M, 96, 96, 3) uint8 head-camera images."""
    success: bool = False
    seed: int = -1
    """Scene seed (-1 where not simulated)."""

    def __post_init__(self) -> None:
        t, d = self.state.shape if self.state.ndim == 2 else (-1, -1)
        problems = []
        if self.time.shape != (t,) or self.action.shape != (t, d) or d != len(self.names):
            problems.append(f"time {self.time.shape}, state {self.state.shape}, action {self.action.shape} and "
                            f"{len(self.names)} names disagree")
        if self.images.ndim != 4 or self.images.shape[0] != self.image_time.shape[0] or self.images.dtype != np.uint8:
            problems.append(f"images {self.images.shape} {self.images.dtype} do not match "
                            f"{self.image_time.shape} times")
        if t < 2 or self.image_time.shape[0] < 1:
            problems.append(f"needs at least 2 control steps and 1 image, got {t} and {self.image_time.shape[0]}")
        if not (np.isfinite(self.state).all() and np.isfinite(self.action).all() and np.isfinite(self.time).all()):
            problems.append("non-finite values in time, state or action")
        if t >= 2 and np.any(np.diff(self.time) <= 0):
            problems.append("times are not increasing")
        if problems:
            raise EpisodeError(f"raw episode ({self.task!r}): {'; '.join(problems)}")

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    def save(self, path: str | Path) -> Path:
        """Write atomically as ``.npz``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".npz", dir=path.parent)
        os.close(fd)
        try:
            np.savez_compressed(
                tmp, task=np.array(self.task), names=np.array(self.names), time=self.time, state=self.state,
                action=self.action, image_time=self.image_time, images=self.images,
                success=np.array(self.success), seed=np.array(self.seed),
            )
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return path

    @classmethod
    def load(cls, path: str | Path) -> RawEpisode:
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as f:
                return cls(
                    task=str(f["task"]), names=tuple(str(n) for n in f["names"]), time=f["time"],
                    state=f["state"], action=f["action"], image_time=f["image_time"], images=f["images"],
                    success=bool(f["success"]), seed=int(f["seed"]),
                )
        except EpisodeError as exc:
            raise EpisodeError(f"{path}: {exc}") from None
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise EpisodeError(f"{path}: not a readable raw episode ({exc})") from None


@dataclass(frozen=True)
class Episode:
    """An episode at the dataset rate: sample k at ``timestamp[k] = k / fps``."""

    task: str
    timestamp: np.ndarray
    state: np.ndarray
    """(N, D) float32."""
    action: np.ndarray
    images: np.ndarray
    """(N, 96, 96, 3) uint8."""

    def __len__(self) -> int:
        return len(self.timestamp)


def resample(raw: RawEpisode, fps: float) -> Episode:
    """Resample to `fps`: joints and actions interpolated linearly, images from the nearest camera frame."""
    if fps <= 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    t0 = raw.time[0]
    n = int(np.floor(raw.duration * fps + 1e-9)) + 1
    t = np.arange(n) / fps
    src = raw.time - t0

    def interp(values: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(t, src, values[:, j]) for j in range(values.shape[1])], axis=1).astype(np.float32)

    image_src = raw.image_time - t0
    right = np.clip(np.searchsorted(image_src, t), 0, len(image_src) - 1)
    left = np.clip(right - 1, 0, len(image_src) - 1)
    nearest = np.where(np.abs(image_src[left] - t) <= np.abs(image_src[right] - t), left, right)
    return Episode(raw.task, t.astype(np.float32), interp(raw.state), interp(raw.action), raw.images[nearest])
