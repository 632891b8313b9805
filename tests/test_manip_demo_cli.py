"""`toddlerbot manip demo` end to end: the dataset it writes, read back without our reader (pyarrow + PyAV)."""

from __future__ import annotations

import json

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")
av = pytest.importorskip("av")


@pytest.mark.slow
def test_demo_dataset_reads_back_with_consistent_counts(tmp_path):
    from typer.testing import CliRunner

    from toddlerbot.cli.main import app

    out = tmp_path / "ds"
    result = CliRunner().invoke(app, ["manip", "demo", "--task", "pick", "--episodes", "4", "--seed", "4242",
                                      "-o", str(out)])
    assert result.exit_code == 0, result.output
    info = json.loads((out / "meta/info.json").read_text())
    data = pq.read_table(out / "data/chunk-000/file-000.parquet")
    episodes = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet")
    with av.open(str(out / "videos/observation.images.head/chunk-000/file-000.mp4")) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert info["total_episodes"] == 4 == episodes.num_rows
    assert data.num_rows == info["total_frames"] == len(frames) == sum(episodes.column("length").to_pylist())
    assert frames[0].shape == (96, 96, 3)
    state = np.array(data.column("observation.state").to_pylist(), dtype=np.float32)
    action = np.array(data.column("action").to_pylist(), dtype=np.float32)
    names = info["features"]["action"]["names"]
    assert state.shape == action.shape == (data.num_rows, 16) and np.isfinite(state).all()
    grip = names.index("right_gripper_drive")
    ep = np.array(data.column("episode_index").to_pylist())
    for e in range(4):
        assert action[ep == e, grip].max() > 1.9  # every episode closes the gripper (to 0.75 of its range)...
        assert action[ep == e][0, grip] < 0.1  # ...from open
    # the low-gain follower lags its targets: actions and observations differ (what the policy learns from)
    assert np.abs(action - state)[:, names.index("right_shoulder_pitch")].mean() > 0.01
    assert len(list((out / "raw").glob("episode_*.npz"))) == 4
