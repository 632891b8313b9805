"""What training reads: a window dataset (protocol), its split by episode, its min-max ranges, and the adapter
from a dataset directory to windows.

A window is one training sample at one frame of one episode, at the policy rate (10 Hz):

- ``observation.state`` (n_obs_steps, state_dim) float32: joint angles, rad (the history ending at the frame);
- ``observation.images.head`` (n_obs_steps, 3, H, W) uint8: head-camera images (not needed by ``encoder="none"``);
- ``action`` (horizon, action_dim) float32: joint targets starting at the frame;
- ``action_is_pad`` (horizon,) bool: True where the episode had ended and the last action was repeated;
- ``episode_index``: int, the episode the window belongs to.

A dataset may also offer ``batch(indices)`` (every field stacked, gathered at once: what training uses when
present), and carry ``window_episodes`` (len,) int, the episode of every window, to spare a pass over the
samples when splitting, and ``state_names`` / ``action_names`` (joint names), which the checkpoint keeps.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
from torch.utils.data import Subset

from toddlerbot.datasets import dataset as demonstrations
from toddlerbot.datasets.dataset import DatasetError
from toddlerbot.dp.policy import ACTION, ACTION_PAD, IMAGE, STATE


class WindowDataset(Protocol):
    def __len__(self) -> int: ...

    def __getitem__(self, index: int) -> dict[str, Any]: ...


def window_episodes(dataset: WindowDataset) -> np.ndarray:
    """Episode index of every window (from ``dataset.window_episodes`` when present, else from the samples)."""
    known = getattr(dataset, "window_episodes", None)
    if known is not None:
        episodes = np.asarray(known, dtype=np.int64)
    else:
        episodes = np.array([int(dataset[i]["episode_index"]) for i in range(len(dataset))], dtype=np.int64)
    if len(episodes) != len(dataset):
        raise DatasetError(f"window_episodes has {len(episodes)} entries for {len(dataset)} windows")
    return episodes


def split_by_episode(dataset: WindowDataset, val_fraction: float, seed: int) -> tuple[Subset, Subset, dict]:
    """Train and validation subsets with no episode in both; ``info`` lists the episodes of each.

    ``round(val_fraction * episodes)`` episodes (at least 1 when ``val_fraction > 0``, and at least one left for
    training) are drawn with ``seed``; every window of a validation episode is in the validation subset.
    """
    episodes = window_episodes(dataset)
    unique = np.unique(episodes)
    n_val = 0 if val_fraction <= 0 else max(1, round(val_fraction * len(unique)))
    if n_val >= len(unique):
        raise DatasetError(f"{len(unique)} episode(s) cannot be split into training and {n_val} validation "
                           "episode(s); record more episodes or pass val_fraction 0")
    val_episodes = np.sort(np.random.default_rng(seed).choice(unique, size=n_val, replace=False))
    in_val = np.isin(episodes, val_episodes)
    info = {"train_episodes": sorted(int(e) for e in np.setdiff1d(unique, val_episodes)),
            "val_episodes": [int(e) for e in val_episodes]}
    return (Subset(dataset, np.flatnonzero(~in_val).tolist()), Subset(dataset, np.flatnonzero(in_val).tolist()),
            info)


def collate(samples: Sequence[dict[str, Any]], keys: Sequence[str]) -> dict[str, torch.Tensor]:
    """Stack the named fields of samples into batch tensors (dtypes kept: uint8 images stay uint8)."""
    return {k: torch.as_tensor(np.stack([np.asarray(s[k]) for s in samples])) for k in keys}


def gather(dataset: WindowDataset, indices: Sequence[int], keys: Sequence[str]) -> dict[str, torch.Tensor]:
    """Batch tensors of windows ``indices`` of ``dataset`` (through any `Subset` to its base): one gather per field
    where the base offers ``batch(indices)``, else sample by sample."""
    base, positions = dataset, list(indices)
    while isinstance(base, Subset):
        positions = [base.indices[i] for i in positions]
        base = base.dataset
    if hasattr(base, "batch"):
        arrays = base.batch(positions)
        return {k: torch.as_tensor(arrays[k]) for k in keys}
    return collate([base[i] for i in positions], keys)


def batch_keys(uses_images: bool) -> tuple[str, ...]:
    return (STATE, ACTION, ACTION_PAD, IMAGE) if uses_images else (STATE, ACTION, ACTION_PAD)


def check_sample(sample: dict[str, Any], n_obs: int, horizon: int, uses_images: bool) -> tuple[int, int]:
    """Validate one window's fields and shapes; returns (state_dim, action_dim)."""
    for key in batch_keys(uses_images):
        if key not in sample:
            raise DatasetError(f"window sample has no {key!r} (fields: {', '.join(sorted(sample))})")
    state, action = np.asarray(sample[STATE]), np.asarray(sample[ACTION])
    if state.ndim != 2 or state.shape[0] != n_obs:
        raise DatasetError(f"{STATE} has shape {state.shape}, expected ({n_obs}, state_dim)")
    if action.ndim != 2 or action.shape[0] != horizon:
        raise DatasetError(f"{ACTION} has shape {action.shape}, expected ({horizon}, action_dim)")
    if uses_images:
        images = np.asarray(sample[IMAGE])
        if images.dtype != np.uint8 or images.ndim != 4 or images.shape[:2] != (n_obs, 3):
            raise DatasetError(f"{IMAGE} is {images.dtype} {images.shape}, expected uint8 ({n_obs}, 3, H, W)")
    return state.shape[1], action.shape[1]


def value_ranges(dataset: WindowDataset, batch: int = 256) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per-dimension (min, max) of state and of the non-padded actions over all windows of ``dataset``."""
    lo: dict[str, np.ndarray] = {}
    hi: dict[str, np.ndarray] = {}
    for start in range(0, len(dataset), batch):
        samples = [dataset[i] for i in range(start, min(start + batch, len(dataset)))]
        state = np.concatenate([np.asarray(s[STATE], np.float32) for s in samples])
        action = np.concatenate([np.asarray(s[ACTION], np.float32)[~np.asarray(s[ACTION_PAD], bool)]
                                 for s in samples])
        for key, values in ((STATE, state), (ACTION, action)):
            if not np.isfinite(values).all():
                raise DatasetError(f"{key} has non-finite values in windows {start}..{start + len(samples) - 1}")
            if len(values):
                lo[key] = np.minimum(lo.get(key, values.min(0)), values.min(0))
                hi[key] = np.maximum(hi.get(key, values.max(0)), values.max(0))
    if set(lo) != {STATE, ACTION}:
        raise DatasetError("the training windows hold no (non-padded) state and action values")
    return {k: (lo[k], hi[k]) for k in lo}


def channel_first(images: np.ndarray) -> np.ndarray:
    """Camera/dataset images (..., H, W, 3) uint8 -> the network's layout (..., 3, H, W), dtype kept; used for the
    training windows and for the live head-camera images alike."""
    return np.ascontiguousarray(np.moveaxis(np.asarray(images), -1, -3))


class ChannelFirstWindows:
    """Adapter: `dataset.Windows` (images (n_obs, H, W, 3)) -> this module's protocol (3, H, W)."""

    def __init__(self, windows: Any) -> None:
        self.windows = windows
        self.window_episodes = np.asarray(windows.dataset.episode_index)[np.asarray(windows.frames)]
        self.state_names = self.action_names = tuple(windows.dataset.names)  # one name list for both

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, index: int) -> dict[str, Any]:
        sample = {key: value[0] for key, value in self.batch([index]).items()}
        sample["episode_index"] = int(sample["episode_index"])
        return sample

    def batch(self, indices: Sequence[int]) -> dict[str, np.ndarray]:
        samples = self.windows.batch(indices)
        if IMAGE in samples:
            samples[IMAGE] = channel_first(samples[IMAGE])
        samples["episode_index"] = self.window_episodes[np.asarray(indices, dtype=np.int64)]
        return samples


def open_window_dataset(path: str | Path, n_obs_steps: int, horizon: int) -> WindowDataset:
    """The one place `dp train` touches the dataset format: a LeRobot v3.0 dataset directory (read with
    `lerobot_reader`, which needs the ``manip`` extra) or its decoded ``.npz`` copy (`dataset.load_decoded`, numpy
    only: for machines without PyAV/pyarrow) -> training windows."""
    path = Path(path)
    if path.is_file() and path.suffix == ".npz":
        loaded = demonstrations.load_decoded(path)
    elif path.is_dir():
        from toddlerbot.datasets import lerobot_reader

        loaded = lerobot_reader.load_dataset(path)
    else:
        raise DatasetError(f"{path}: expected a dataset directory or a decoded .npz (toddlerbot manip dataset decode)")
    config = demonstrations.WindowConfig(obs_horizon=n_obs_steps, action_horizon=horizon)
    return ChannelFirstWindows(demonstrations.Windows(loaded, config))
