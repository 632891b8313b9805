"""A demonstration dataset in memory and its training windows; also a decoded copy of it in one ``.npz`` file.

`Dataset` is what `lerobot_reader.load_dataset` returns (all rows in memory, images decoded). `save_decoded` /
`load_decoded` write and read it as one NumPy archive (no pickle) so a machine without PyAV and pyarrow (the
``manip`` extra), e.g. a GPU node, can train on it: ``toddlerbot manip dataset decode DIR -o data.npz``.

`Windows` gives training samples the way LeRobot's ``delta_timestamps`` do: ``obs_horizon`` observations ending
at frame i and ``action_horizon`` actions starting at frame i, repeated at the episode's ends and flagged as
padding, never crossing into the neighbouring episode.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_savez

IMAGE_KEY = "observation.images.head"
DECODED_FORMAT = "toddlerbot-decoded-dataset/1"
_ARRAYS = ("state", "action", "timestamp", "episode_index", "images", "episode_bounds")


class DatasetError(ToddlerbotError):
    """A dataset (on disk or as training windows) is missing, incomplete, inconsistent or too small to split."""


@dataclass(frozen=True)
class Dataset:
    """A loaded dataset: all rows in memory (state, action float32; images uint8 (N, H, W, 3))."""

    root: Path
    info: dict
    state: np.ndarray
    action: np.ndarray
    timestamp: np.ndarray
    episode_index: np.ndarray
    images: np.ndarray
    episode_bounds: np.ndarray
    """(E, 2) [from, to) row range of each episode."""
    tasks: tuple[str, ...]
    stats: dict

    @property
    def fps(self) -> int:
        return int(self.info["fps"])

    @property
    def names(self) -> list[str]:
        return list(self.info["features"]["action"]["names"])

    @property
    def n_episodes(self) -> int:
        return len(self.episode_bounds)

    def __len__(self) -> int:
        return len(self.state)

    def summary(self) -> dict:
        lengths = self.episode_bounds[:, 1] - self.episode_bounds[:, 0]
        return {
            "root": str(self.root), "codebase_version": self.info["codebase_version"], "fps": self.fps,
            "episodes": self.n_episodes, "frames": len(self), "tasks": list(self.tasks),
            "state_dim": int(self.state.shape[1]), "action_dim": int(self.action.shape[1]),
            "image_shape": list(self.info["features"][IMAGE_KEY]["shape"]),
            "episode_seconds": {"min": float(lengths.min() / self.fps), "mean": float(lengths.mean() / self.fps),
                                "max": float(lengths.max() / self.fps)},
        }




@dataclass(frozen=True)
class WindowConfig:
    obs_horizon: int = 2
    """Observations per sample, ending at the sample's frame."""
    action_horizon: int = 16
    """Actions per sample, starting at the sample's frame."""

    def __post_init__(self) -> None:
        if self.obs_horizon < 1 or self.action_horizon < 1:
            raise ValueError(f"horizons must be >= 1, got {self.obs_horizon}, {self.action_horizon}")


class Windows:
    """Training samples of a dataset, restricted to some episodes (split train/validation by episode)."""

    def __init__(self, dataset: Dataset, config: WindowConfig | None = None,
                 episodes: Sequence[int] | None = None) -> None:
        self.dataset = dataset
        self.config = config or WindowConfig()
        chosen = range(dataset.n_episodes) if episodes is None else episodes
        self.episodes = tuple(int(e) for e in chosen)
        bad = [e for e in self.episodes if not 0 <= e < dataset.n_episodes]
        if bad:
            raise ValueError(f"episode(s) {bad} not in 0..{dataset.n_episodes - 1}")
        self.frames = np.concatenate([np.arange(*dataset.episode_bounds[e]) for e in self.episodes]) if (
            self.episodes) else np.zeros(0, dtype=np.int64)

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, i: int) -> dict[str, np.ndarray]:
        """Sample i: ``observation.state`` (To, D), ``observation.images.head`` (To, H, W, 3) uint8,
        ``action`` (Ta, D), and boolean ``observation_is_pad`` (To,), ``action_is_pad`` (Ta,)."""
        return {key: value[0] for key, value in self.batch([i]).items()}

    def batch(self, indices: Sequence[int]) -> dict[str, np.ndarray]:
        """Samples ``indices`` stacked (a leading batch axis on every field of `__getitem__`), gathered with one
        index array per field rather than sample by sample (a GPU trains faster than samples are cut one by one)."""
        ds, cfg = self.dataset, self.config
        frames = self.frames[np.asarray(indices, dtype=np.int64)]
        bounds = ds.episode_bounds[ds.episode_index[frames]]
        start, last = bounds[:, :1], bounds[:, 1:] - 1
        obs_idx = frames[:, None] + np.arange(-cfg.obs_horizon + 1, 1)
        act_idx = frames[:, None] + np.arange(cfg.action_horizon)
        obs_clamped = np.clip(obs_idx, start, last)
        act_clamped = np.clip(act_idx, start, last)
        samples = {
            "observation.state": ds.state[obs_clamped],
            "action": ds.action[act_clamped],
            "observation_is_pad": obs_idx != obs_clamped,
            "action_is_pad": act_idx != act_clamped,
        }
        if ds.images.shape[1]:
            samples[IMAGE_KEY] = ds.images[obs_clamped]
        return samples


def bounds_tile(bounds: np.ndarray, rows: int) -> bool:
    """Do the (E, 2) [from, to) episode row ranges cover rows 0..rows in order, each episode non-empty?"""
    bounds = np.asarray(bounds)
    if bounds.ndim != 2 or bounds.shape[1] != 2 or len(bounds) == 0:
        return False
    starts = np.concatenate([[0], bounds[:-1, 1]])
    return bool(np.all(bounds[:, 0] == starts) and bounds[-1, 1] == rows and np.all(bounds[:, 1] > bounds[:, 0]))


def save_decoded(dataset: Dataset, path: str | Path) -> Path:
    """Write ``dataset`` (images decoded) as one compressed ``.npz``; metadata as JSON text inside it."""
    meta = {"format": DECODED_FORMAT, "root": str(dataset.root), "info": dataset.info, "tasks": list(dataset.tasks),
            "stats": dataset.stats}
    arrays = {name: getattr(dataset, name) for name in _ARRAYS}
    return atomic_savez(path, {"meta": np.array(json.dumps(meta)), **arrays}, compressed=True)


def load_decoded(path: str | Path) -> Dataset:
    """Read a `save_decoded` file back (``allow_pickle=False``); one-line errors for anything else."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: no such decoded dataset file")
    try:
        with np.load(path, allow_pickle=False) as archive:
            contents = {name: archive[name] for name in archive.files}
    except (OSError, ValueError, EOFError) as exc:
        raise DatasetError(f"{path}: not a readable .npz ({exc})") from None
    missing = [name for name in ("meta", *_ARRAYS) if name not in contents]
    if missing:
        raise DatasetError(f"{path}: missing array(s) {', '.join(missing)}; write it with `toddlerbot manip dataset "
                           "decode`")
    meta = json.loads(str(contents["meta"]))
    if meta.get("format") != DECODED_FORMAT:
        raise DatasetError(f"{path}: format {meta.get('format')!r}, expected {DECODED_FORMAT!r}")
    n = len(contents["state"])
    for name in ("action", "timestamp", "episode_index", "images"):
        if len(contents[name]) != n:
            raise DatasetError(f"{path}: {name} has {len(contents[name])} rows, state has {n}")
    bounds = contents["episode_bounds"]
    if not bounds_tile(bounds, n):
        raise DatasetError(f"{path}: episode_bounds do not tile rows 0..{n}")
    for name in ("state", "action"):
        if not np.isfinite(contents[name]).all():
            raise DatasetError(f"{path}: {name} has NaN/inf values")
    return Dataset(Path(meta["root"]), meta["info"], contents["state"].astype(np.float32),
                   contents["action"].astype(np.float32), contents["timestamp"], contents["episode_index"],
                   contents["images"], bounds.astype(np.int64), tuple(meta["tasks"]), meta["stats"])
