"""Write episodes as a LeRobot v3.0 dataset with pyarrow and PyAV (the ``lerobot`` package is not needed).

Layout (one chunk, one file per kind; episodes are concatenated, rows and video frames in the same order)::

    meta/info.json                                    codebase_version "v3.0", fps, features, paths
    meta/stats.json                                   min, max, mean, std, count per feature
    meta/tasks.parquet                                task_index, task
    meta/episodes/chunk-000/file-000.parquet          one row per episode: length, row range, video range
    data/chunk-000/file-000.parquet                   observation.state, action, timestamp, frame_index,
                                                      episode_index, index, task_index
    videos/observation.images.head/chunk-000/file-000.mp4

Everything is written into a temporary directory beside the target and renamed into place at the end, so a
failed write leaves no half dataset.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import av
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from toddlerbot.datasets.dataset import IMAGE_KEY
from toddlerbot.datasets.episode import Episode, RawEpisode

CODEBASE_VERSION = "v3.0"
DATA_FILE = "data/chunk-000/file-000.parquet"
EPISODES_FILE = "meta/episodes/chunk-000/file-000.parquet"
TASKS_FILE = "meta/tasks.parquet"
VIDEO_FILE = f"videos/{IMAGE_KEY}/chunk-000/file-000.mp4"
VIDEO_CODEC = "libx264"
VIDEO_OPTIONS = {"crf": "16", "g": "10", "preset": "veryfast"}
"""Near-lossless H.264 with a keyframe every second at 10 fps (random access for training)."""


RAW_DIR = "raw"
"""Sub-folder of a dataset holding the raw (50 Hz) episodes it was made from, ``episode_{index:06d}.npz``."""


def write_dataset(root: str | Path, episodes: Sequence[Episode], names: Sequence[str], fps: int,
                  robot_type: str = "toddlerbot_gripper", overwrite: bool = False,
                  raw_episodes: Sequence[RawEpisode] = ()) -> Path:
    """Write `episodes` (all at `fps`, state/action columns named `names`) as a LeRobot v3.0 dataset at `root`,
    with the raw episodes they came from (if given) under ``raw/``."""
    root = Path(root)
    if not episodes:
        raise ValueError("no episodes to write")
    if root.exists() and any(root.iterdir()) and not overwrite:
        raise FileExistsError(f"{root} exists and is not empty")
    root.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{root.name}.", dir=root.parent))
    try:
        _write(tmp, list(episodes), tuple(names), fps, robot_type)
        for i, raw in enumerate(raw_episodes):
            raw.save(tmp / RAW_DIR / f"episode_{i:06d}.npz")
        if root.exists():
            shutil.rmtree(root)
        tmp.rename(root)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return root


def _write(root: Path, episodes: list[Episode], names: tuple[str, ...], fps: int, robot_type: str) -> None:
    tasks = sorted({e.task for e in episodes})
    task_index = {t: i for i, t in enumerate(tasks)}
    lengths = np.array([len(e) for e in episodes])
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    total = int(lengths.sum())
    height, width = episodes[0].images.shape[1:3]

    state = np.concatenate([e.state for e in episodes]).astype(np.float32)
    action = np.concatenate([e.action for e in episodes]).astype(np.float32)
    columns = {
        "observation.state": state,
        "action": action,
        "timestamp": np.concatenate([e.timestamp for e in episodes]).astype(np.float32),
        "frame_index": np.concatenate([np.arange(n) for n in lengths]).astype(np.int64),
        "episode_index": np.repeat(np.arange(len(episodes)), lengths).astype(np.int64),
        "index": np.arange(total, dtype=np.int64),
        "task_index": np.concatenate([np.full(len(e), task_index[e.task]) for e in episodes]).astype(np.int64),
    }
    _write_parquet(root / DATA_FILE, {k: _vector_column(v) if v.ndim == 2 else pa.array(v) for k, v in columns.items()})

    images = np.concatenate([e.images for e in episodes])
    _write_video(root / VIDEO_FILE, images, fps)
    _write_parquet(root / TASKS_FILE, {"task_index": pa.array(np.arange(len(tasks), dtype=np.int64)),
                                       "task": pa.array(tasks)}, metadata={b"pandas": _TASKS_PANDAS_METADATA})

    ends = starts + lengths
    episode_rows = {
        "episode_index": pa.array(np.arange(len(episodes), dtype=np.int64)),
        "tasks": pa.array([[e.task] for e in episodes], type=pa.list_(pa.string())),
        "length": pa.array(lengths.astype(np.int64)),
        "data/chunk_index": pa.array(np.zeros(len(episodes), dtype=np.int64)),
        "data/file_index": pa.array(np.zeros(len(episodes), dtype=np.int64)),
        "dataset_from_index": pa.array(starts.astype(np.int64)),
        "dataset_to_index": pa.array(ends.astype(np.int64)),
        f"videos/{IMAGE_KEY}/chunk_index": pa.array(np.zeros(len(episodes), dtype=np.int64)),
        f"videos/{IMAGE_KEY}/file_index": pa.array(np.zeros(len(episodes), dtype=np.int64)),
        f"videos/{IMAGE_KEY}/from_timestamp": pa.array(starts / fps),
        f"videos/{IMAGE_KEY}/to_timestamp": pa.array(ends / fps),
        "meta/episodes/chunk_index": pa.array(np.zeros(len(episodes), dtype=np.int64)),
        "meta/episodes/file_index": pa.array(np.zeros(len(episodes), dtype=np.int64)),
    }
    for key, values in (("observation.state", state), ("action", action)):
        per_episode = [_stats(values[s:e]) for s, e in zip(starts, ends)]
        for stat in ("min", "max", "mean", "std"):
            episode_rows[f"stats/{key}/{stat}"] = _vector_column(np.stack([p[stat] for p in per_episode]))
        episode_rows[f"stats/{key}/count"] = pa.array([int(p["count"][0]) for p in per_episode], type=pa.int64())
    _write_parquet(root / EPISODES_FILE, episode_rows)

    stats = {key: _stats(values) for key, values in columns.items()}
    stats[IMAGE_KEY] = _image_stats(images)
    _write_json(root / "meta/stats.json", {k: {s: v.tolist() for s, v in d.items()} for k, d in stats.items()})
    _write_json(root / "meta/info.json", info_dict(names, fps, len(episodes), total, len(tasks), height, width,
                                                   robot_type))


# LeRobot reads tasks.parquet with pandas and takes the task strings from the index: this pandas metadata makes
# the "task" column that index, as pandas itself would have written it.
_TASKS_PANDAS_METADATA = json.dumps({
    "index_columns": ["task"],
    "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
                        "metadata": {"encoding": "UTF-8"}}],
    "columns": [
        {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
         "metadata": None},
        {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object", "metadata": None},
    ],
    "creator": {"library": "pyarrow", "version": pa.__version__},
}).encode()


def info_dict(names: Sequence[str], fps: int, episodes: int, frames: int, tasks: int, height: int, width: int,
              robot_type: str) -> dict:
    """The ``meta/info.json`` content of a one-chunk dataset."""
    scalar = {"shape": [1], "names": None}
    return {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": robot_type,
        "total_episodes": episodes,
        "total_frames": frames,
        "total_tasks": tasks,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500,
        "fps": fps,
        "splits": {"train": f"0:{episodes}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": {
            IMAGE_KEY: {
                "dtype": "video", "shape": [height, width, 3], "names": ["height", "width", "channels"],
                "info": {"video.height": height, "video.width": width, "video.codec": "h264",
                         "video.pix_fmt": "yuv420p", "video.is_depth_map": False, "video.fps": fps,
                         "video.channels": 3, "has_audio": False},
            },
            "observation.state": {"dtype": "float32", "shape": [len(names)], "names": list(names)},
            "action": {"dtype": "float32", "shape": [len(names)], "names": list(names)},
            "timestamp": {"dtype": "float32", **scalar},
            "frame_index": {"dtype": "int64", **scalar},
            "episode_index": {"dtype": "int64", **scalar},
            "index": {"dtype": "int64", **scalar},
            "task_index": {"dtype": "int64", **scalar},
        },
    }


def _vector_column(values: np.ndarray) -> pa.Array:
    values = np.ascontiguousarray(values)
    return pa.FixedSizeListArray.from_arrays(pa.array(values.ravel()), values.shape[1])


def _write_parquet(path: Path, columns: dict[str, pa.Array], metadata: dict[bytes, bytes] | None = None) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(columns, metadata=metadata), path)


def _write_json(path: Path, content: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(content, indent=2) + "\n")


def _write_video(path: Path, frames: np.ndarray, fps: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream(VIDEO_CODEC, rate=fps, options=VIDEO_OPTIONS)
        stream.width, stream.height = frames.shape[2], frames.shape[1]
        stream.pix_fmt = "yuv420p"
        for i, frame in enumerate(frames):
            video_frame = av.VideoFrame.from_ndarray(frame, format="rgb24")
            video_frame.pts = i
            container.mux(stream.encode(video_frame))
        container.mux(stream.encode())


def _stats(values: np.ndarray) -> dict[str, np.ndarray]:
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    return {"min": values.min(0), "max": values.max(0), "mean": values.mean(0), "std": values.std(0),
            "count": np.array([len(values)])}


def _image_stats(images: np.ndarray) -> dict[str, np.ndarray]:
    """Per-channel statistics of images scaled to [0, 1], shaped (3, 1, 1) as LeRobot stores them."""
    pixels = images.reshape(-1, 3).astype(np.float64) / 255.0
    s = _stats(pixels)
    return {k: (v.reshape(3, 1, 1) if k != "count" else np.array([len(images)])) for k, v in s.items()}
