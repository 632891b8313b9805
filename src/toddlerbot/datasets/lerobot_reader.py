"""Read and validate a LeRobot v3.0 dataset written by `lerobot_writer` into a `dataset.Dataset`.

`load_dataset` checks everything a trainer relies on and raises `DatasetError` (one line naming the file) for a
missing or truncated file, a row count that disagrees with ``meta/info.json``, NaN rows, episode ranges that do
not tile the data, or a video whose decoded frame count differs from the rows.

Training windows are cut from the loaded dataset by `dataset.Windows`.
"""

from __future__ import annotations

import json
from pathlib import Path

import av
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from toddlerbot.datasets.dataset import Dataset, DatasetError, bounds_tile
from toddlerbot.datasets.lerobot_writer import (
    CODEBASE_VERSION,
    DATA_FILE,
    EPISODES_FILE,
    TASKS_FILE,
    VIDEO_FILE,
)
from toddlerbot.yaml_input import read_text

DATA_COLUMNS = ("observation.state", "action", "timestamp", "frame_index", "episode_index", "index", "task_index")


def load_dataset(root: str | Path, decode_video: bool = True) -> Dataset:
    """Load and validate a dataset; `decode_video=False` skips the images (frame count still checked)."""
    root = Path(root)
    info = _read_json(root, "meta/info.json")
    if info.get("codebase_version") != CODEBASE_VERSION:
        raise DatasetError(f"{root / 'meta/info.json'}: codebase_version is {info.get('codebase_version')!r}, "
                           f"expected {CODEBASE_VERSION!r}")
    stats = _read_json(root, "meta/stats.json")
    data = _read_parquet(root, DATA_FILE)
    missing = [c for c in DATA_COLUMNS if c not in data.column_names]
    if missing:
        raise DatasetError(f"{root / DATA_FILE}: missing column(s) {', '.join(missing)}")
    total = int(info.get("total_frames", -1))
    if data.num_rows != total:
        raise DatasetError(f"{root / DATA_FILE}: {data.num_rows} rows, but meta/info.json says total_frames={total}")
    state = _matrix(data, "observation.state", root)
    action = _matrix(data, "action", root)
    for name, values in (("observation.state", state), ("action", action)):
        bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
        if bad.size:
            raise DatasetError(f"{root / DATA_FILE}: {bad.size} row(s) with NaN/inf in {name}, first at index "
                               f"{int(bad[0])}")
    index = data.column("index").to_numpy()
    if not np.array_equal(index, np.arange(total)):
        raise DatasetError(f"{root / DATA_FILE}: column index is not 0..{total - 1} in order")
    episode_index = data.column("episode_index").to_numpy()

    episodes = _read_parquet(root, EPISODES_FILE)
    bounds = np.stack([episodes.column("dataset_from_index").to_numpy(),
                       episodes.column("dataset_to_index").to_numpy()], axis=1).astype(np.int64)
    if len(bounds) != int(info.get("total_episodes", -1)):
        raise DatasetError(f"{root / EPISODES_FILE}: {len(bounds)} episodes, but meta/info.json says "
                           f"total_episodes={info.get('total_episodes')}")
    if not bounds_tile(bounds, total):
        raise DatasetError(f"{root / EPISODES_FILE}: episode row ranges do not tile rows 0..{total}")
    for e, (start, end) in enumerate(bounds):
        if np.any(episode_index[start:end] != e):
            raise DatasetError(f"{root / DATA_FILE}: rows {start}..{end - 1} are not all episode_index {e}")
    tasks = tuple(str(t) for t in _read_parquet(root, TASKS_FILE).column("task").to_pylist())

    frames = _decode_video(root / VIDEO_FILE, keep=decode_video)
    if len(frames) != total:
        raise DatasetError(f"{root / VIDEO_FILE}: {len(frames)} video frames, but the data has {total} rows")
    images = np.stack(frames) if decode_video else np.zeros((total, 0, 0, 3), dtype=np.uint8)
    return Dataset(root, info, state, action, data.column("timestamp").to_numpy(), episode_index, images, bounds,
                   tasks, stats)


MAX_METADATA_BYTES = 10_000_000
"""Largest JSON metadata file of a dataset read, bytes (meta/info.json of a 10,000-episode set is about 5 kB)."""


def _read_json(root: Path, rel: str) -> dict:
    path = root / rel
    if not path.exists():
        raise DatasetError(f"{path}: missing")
    try:
        return json.loads(read_text(path, "dataset metadata file", DatasetError, MAX_METADATA_BYTES))
    except json.JSONDecodeError as exc:
        raise DatasetError(f"{path}: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None


def _read_parquet(root: Path, rel: str) -> pa.Table:
    path = root / rel
    if not path.exists():
        raise DatasetError(f"{path}: missing")
    try:
        return pq.read_table(path)
    except (pa.ArrowException, OSError) as exc:
        raise DatasetError(f"{path}: unreadable parquet (truncated?): {str(exc).splitlines()[0]}") from None


def _matrix(table: pa.Table, column: str, root: Path) -> np.ndarray:
    col = table.column(column).combine_chunks()
    if not pa.types.is_fixed_size_list(col.type) and not pa.types.is_list(col.type):
        raise DatasetError(f"{root / DATA_FILE}: column {column} is {col.type}, expected a list of float32")
    flat = col.flatten().to_numpy(zero_copy_only=False).astype(np.float32)
    width = len(flat) // max(1, len(col))
    if width * len(col) != len(flat):
        raise DatasetError(f"{root / DATA_FILE}: column {column} has rows of different lengths")
    return flat.reshape(len(col), width)


def _decode_video(path: Path, keep: bool) -> list[np.ndarray]:
    if not path.exists():
        raise DatasetError(f"{path}: missing")
    frames: list[np.ndarray] = []
    try:
        with av.open(str(path)) as container:
            for frame in container.decode(video=0):
                frames.append(frame.to_ndarray(format="rgb24") if keep else np.zeros(0, np.uint8))
    except (av.error.FFmpegError, OSError) as exc:
        raise DatasetError(f"{path}: unreadable video (truncated?): {exc}") from None
    return frames
