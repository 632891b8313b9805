"""A LeRobot v3.0 dataset as a Rerun recording: head-camera video, follower state and leader action per joint over
time, episode boundaries and success (`toddlerbot manip dataset view`).

Entities (timeline ``time``: seconds from the first shown frame, episodes back to back; ``frame``: the dataset row):

* ``camera/head``: one image per row (the dataset's decoded video);
* ``joints/<motor>/state`` and ``joints/<motor>/action``: follower angle and leader target, rad;
* ``episode/index`` and ``episode/success`` (1 succeeded, 0 failed; absent when the dataset does not say);
* ``episodes``: one text line at each episode's first frame (index, task, length, success).

Success is read from the raw episode a row range came from (``raw/episode_NNNNNN.npz``, field ``success``), the
only place the writer keeps it. The layout (camera and episode log on the left, one plot per joint with state and
action together on the right) is sent as a blueprint, so the viewer opens arranged.

The native viewer we spawn has Rerun's usage analytics off (`spawn_viewer`): no network at run time.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from toddlerbot.datasets.dataset import Dataset, DatasetError
from toddlerbot.datasets.lerobot_writer import RAW_DIR

APP_ID = "toddlerbot_dataset"
STATE_COLOR, ACTION_COLOR = (40, 120, 220), (230, 120, 30)
ANALYTICS_OFF = {"CI": "1"}
"""Added to the environment of the viewer we start. rerun-sdk 0.41 reads no variable that only switches analytics
off: the viewer's pipeline (re_analytics, native/pipeline.rs) stays off while ``CI`` is set, unless
``FORCE_RERUN_ANALYTICS`` is truthy (checked first: the user's explicit opt-in still wins); `rerun analytics
disable` is the user's own persistent opt-out. A ``CI`` the user set is kept as it is."""
VIEWER_PORT = 9876
"""Rerun's default viewer port."""


def episode_success(root: Path, episode: int) -> bool | None:
    """Whether episode `episode` succeeded, from its raw file (None when there is none or it does not say)."""
    path = root / RAW_DIR / f"episode_{episode:06d}.npz"
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as raw:  # reads only the member asked for
            return bool(raw["success"]) if "success" in raw.files else None
    except (OSError, ValueError, KeyError):
        return None


def choose_episodes(dataset: Dataset, episode: int | None) -> list[int]:
    if episode is None:
        return list(range(dataset.n_episodes))
    if not 0 <= episode < dataset.n_episodes:
        raise DatasetError(f"{dataset.root}: --episode {episode}: the dataset has episodes 0-{dataset.n_episodes - 1}")
    return [episode]


def blueprint(names: Sequence[str]) -> rrb.Blueprint:
    plots = [rrb.TimeSeriesView(origin=f"joints/{n}", name=n) for n in names]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(rrb.Spatial2DView(origin="camera/head", name="head camera"),
                         rrb.TimeSeriesView(origin="episode", name="episode, success"),
                         rrb.TextLogView(origin="episodes", name="episodes"), row_shares=[3, 1, 1]),
            rrb.Grid(*plots),
            column_shares=[1, 3]),
        collapse_panels=True)


def log_dataset(dataset: Dataset, episodes: Sequence[int], recording: rr.RecordingStream) -> dict:
    """Send `episodes` of `dataset` (images decoded) to `recording`; returns what was sent (frames, seconds,
    success per episode)."""
    fps, names = dataset.fps, dataset.names
    rows = np.concatenate([np.arange(*dataset.episode_bounds[e]) for e in episodes])
    seconds = np.arange(len(rows)) / fps
    index = [rr.TimeColumn("time", duration=seconds), rr.TimeColumn("frame", sequence=rows)]
    recording.send_blueprint(blueprint(names))

    for joint, name in enumerate(names):
        for kind, values, color in (("state", dataset.state, STATE_COLOR), ("action", dataset.action, ACTION_COLOR)):
            path = f"joints/{name}/{kind}"
            label = "follower state" if kind == "state" else "leader action"
            recording.log(path, rr.SeriesLines(colors=[color], names=[label], widths=[1.5]), static=True)
            recording.send_columns(path, indexes=index, columns=rr.Scalars.columns(scalars=values[rows, joint]))

    images = dataset.images[rows]
    if images.shape[1]:
        height, width = images.shape[1:3]
        recording.log("camera/head", rr.Image.from_fields(format=rr.components.ImageFormat(
            width=width, height=height, color_model="RGB", channel_datatype="U8")), static=True)
        recording.send_columns("camera/head", indexes=index,
                               columns=rr.Image.columns(buffer=images.reshape(len(images), -1)))

    successes: dict[int, bool | None] = {}
    start = 0
    for e in episodes:
        begin, end = dataset.episode_bounds[e]
        n = int(end - begin)
        success = successes[e] = episode_success(dataset.root, e)
        span = [rr.TimeColumn("time", duration=seconds[start:start + n]),
                rr.TimeColumn("frame", sequence=rows[start:start + n])]
        recording.send_columns("episode/index", indexes=span, columns=rr.Scalars.columns(scalars=np.full(n, e)))
        if success is not None:
            recording.send_columns("episode/success", indexes=span,
                                   columns=rr.Scalars.columns(scalars=np.full(n, float(success))))
        recording.set_time("time", duration=seconds[start])
        recording.set_time("frame", sequence=int(begin))
        task = dataset.tasks[0] if len(dataset.tasks) == 1 else "see meta/tasks.parquet"
        said = {True: "yes", False: "NO", None: "not recorded"}[success]
        recording.log("episodes", rr.TextLog(f"episode {e}: {n} frames ({n / fps:.1f} s), task {task!r}, "
                                             f"success: {said}", level="WARN" if success is False else "INFO"))
        start += n
    recording.log("episode/index", rr.SeriesLines(names=["episode"]), static=True)
    recording.log("episode/success", rr.SeriesLines(names=["success"], colors=[(40, 170, 70)]), static=True)
    return {"episodes": list(episodes), "frames": len(rows), "seconds": float(len(rows) / fps),
            "success": {str(e): s for e, s in successes.items()}}


def recording_for(dataset: Dataset) -> rr.RecordingStream:
    return rr.RecordingStream(APP_ID, recording_id=str(dataset.root.resolve()))


def viewer_environment(environ: Mapping[str, str] = os.environ) -> dict[str, str]:
    """The environment of a viewer we start: `environ` plus analytics off where the user has not said, and
    ``RERUN_APP_ONLY`` as rerun's own spawn sets it (no first-run analytics notice)."""
    return {**environ, "RERUN_APP_ONLY": "true", **{k: v for k, v in ANALYTICS_OFF.items() if k not in environ}}


def spawn_viewer(recording: rr.RecordingStream) -> None:
    """Stream `recording` to Rerun's native viewer on `VIEWER_PORT`, starting one (its own session, so a Ctrl-C
    here leaves it open) unless something listens there already, as ``RecordingStream.spawn`` does. Its analytics
    are off: rerun's spawn cannot do that, as it first runs ``rerun --version`` without its extra environment
    (that process starts the analytics pipeline too) and warns when our own process has ``CI`` set."""
    with socket.socket() as probe:
        running = probe.connect_ex(("127.0.0.1", VIEWER_PORT)) == 0
    if not running:
        subprocess.Popen([sys.executable, "-m", "rerun_cli", f"--port={VIEWER_PORT}", "--expect-data-soon"],
                         env=viewer_environment(), stdin=subprocess.DEVNULL, start_new_session=True)
    recording.connect_grpc(f"rerun+http://127.0.0.1:{VIEWER_PORT}/proxy")
