"""Raw episodes, 10 Hz resampling, the LeRobot v3.0 writer, its validation and training windows."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow")
av = pytest.importorskip("av")
pq = pytest.importorskip("pyarrow.parquet")

from toddlerbot.datasets.dataset import DatasetError, WindowConfig, Windows  # noqa: E402
from toddlerbot.datasets.episode import EpisodeError, RawEpisode, resample  # noqa: E402
from toddlerbot.datasets.lerobot_reader import load_dataset  # noqa: E402
from toddlerbot.datasets.lerobot_writer import DATA_FILE, VIDEO_FILE, write_dataset  # noqa: E402

NAMES = ("a", "b")


def _raw(seconds: float, offset: float = 0.0, task: str = "pick up the red cube") -> RawEpisode:
    """50 Hz ramps (state = t + offset, action = 2t), images at 25 Hz (5 ms after the control steps) whose
    brightness encodes their index."""
    t = np.arange(round(seconds * 50) + 1) / 50
    image_time = t[::2] + 0.005
    images = np.zeros((len(image_time), 96, 96, 3), np.uint8)
    images[:] = (np.arange(len(image_time)) * 8 % 256)[:, None, None, None]
    return RawEpisode(task, NAMES, t, np.stack([t + offset, -t], 1), np.stack([2 * t, t], 1), image_time, images)


def _dataset(tmp_path, lengths=(1.0, 0.5)):
    raws = [_raw(s, offset=i) for i, s in enumerate(lengths)]
    root = write_dataset(tmp_path / "ds", [resample(r, 10) for r in raws], NAMES, 10, raw_episodes=raws)
    return root, raws


def test_resample_interpolates_joints_and_takes_the_nearest_image():
    raw = _raw(1.0)
    ep = resample(raw, 10)
    assert len(ep) == 11
    np.testing.assert_allclose(ep.timestamp, np.arange(11) / 10, atol=1e-6)
    np.testing.assert_allclose(ep.state[:, 0], np.arange(11) / 10, atol=1e-6)
    np.testing.assert_allclose(ep.action[:, 0], 2 * np.arange(11) / 10, atol=1e-6)
    # image j is at 0.04 j + 0.005 s: sample k (0.1 k s) is nearest to image round(2.5 k - 0.125)
    expected = [int(np.floor(2.5 * k - 0.125 + 0.5)) for k in range(11)]
    np.testing.assert_array_equal(ep.images[:, 0, 0, 0], np.array(expected) * 8 % 256)


def test_raw_episode_round_trips_without_pickle_and_rejects_nan(tmp_path):
    raw = _raw(0.4)
    back = RawEpisode.load(raw.save(tmp_path / "e.npz"))
    np.testing.assert_array_equal(back.state, raw.state)
    assert back.names == NAMES and back.task == raw.task
    with pytest.raises(EpisodeError, match="non-finite"):
        RawEpisode(raw.task, NAMES, raw.time, raw.state * np.nan, raw.action, raw.image_time, raw.images)
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(EpisodeError, match=r"bad\.npz"):
        RawEpisode.load(tmp_path / "bad.npz")


def test_dataset_counts_agree_for_an_independent_reader(tmp_path):
    root, raws = _dataset(tmp_path)
    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 10
    data = pq.read_table(root / DATA_FILE)
    with av.open(str(root / VIDEO_FILE)) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert data.num_rows == info["total_frames"] == len(frames) == 11 + 6
    assert data.column("observation.state").type.value_type == pa.float32()
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet")
    assert episodes.column("length").to_pylist() == [11, 6]
    assert episodes.column("dataset_from_index").to_pylist() == [0, 11]
    # near-lossless video: the brightness code of every frame survives encoding
    expected = np.concatenate([resample(r, 10).images[:, 0, 0, 0] for r in raws]).astype(float)
    assert np.max(np.abs(np.array([f[40:56, 40:56].mean() for f in frames]) - expected)) < 3
    stats = json.loads((root / "meta/stats.json").read_text())
    assert stats["action"]["max"][0] == pytest.approx(2.0) and stats["action"]["count"] == [17]
    assert len(list((root / "raw").glob("episode_*.npz"))) == 2


def test_windows_pad_at_episode_ends_and_never_cross_episodes(tmp_path):
    root, _ = _dataset(tmp_path)
    ds = load_dataset(root)
    windows = Windows(ds, WindowConfig(obs_horizon=2, action_horizon=4))
    first = windows[0]
    np.testing.assert_allclose(first["observation.state"][:, 0], [0.0, 0.0])
    np.testing.assert_array_equal(first["observation_is_pad"], [True, False])
    assert first["observation.images.head"].shape == (2, 96, 96, 3)
    last_of_first_episode = windows[9]  # frame 9 of 11: actions 9, 10, then padded with 10
    np.testing.assert_allclose(last_of_first_episode["action"][:, 0], [1.8, 2.0, 2.0, 2.0], atol=1e-6)
    np.testing.assert_array_equal(last_of_first_episode["action_is_pad"], [False, False, True, True])
    second = Windows(ds, WindowConfig(2, 4), episodes=[1])
    assert len(second) == 6
    np.testing.assert_allclose(second[0]["observation.state"][:, 0], [1.0, 1.0])  # episode 1 starts at offset 1


def _rejection(root) -> str:
    """The one-line message `load_dataset` refuses `root` with."""
    with pytest.raises(DatasetError) as err:
        load_dataset(root)
    return str(err.value)


def test_truncated_parquet_is_rejected_naming_the_file(tmp_path):
    root, _ = _dataset(tmp_path)
    path = root / DATA_FILE
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    message = _rejection(root)
    assert re.search(r"data/chunk-000/file-000\.parquet: unreadable parquet", message)
    assert "\n" not in message


def test_nan_rows_are_rejected_naming_the_file_and_row(tmp_path):
    root, _ = _dataset(tmp_path)
    table = pq.read_table(root / DATA_FILE)
    state = np.stack(table.column("observation.state").to_pylist()).astype(np.float32)
    state[5, 1] = np.nan
    column = pa.FixedSizeListArray.from_arrays(pa.array(state.ravel()), 2)
    pq.write_table(table.set_column(0, "observation.state", column), root / DATA_FILE)
    message = _rejection(root)
    assert re.search(r"file-000\.parquet: 1 row\(s\) with NaN/inf in observation.state, first at index 5", message)
    assert "\n" not in message


def test_video_with_too_few_frames_is_rejected(tmp_path):
    root, _ = _dataset(tmp_path)
    other, _ = _dataset(tmp_path / "short", lengths=(1.0,))
    (root / VIDEO_FILE).write_bytes((other / VIDEO_FILE).read_bytes())
    message = _rejection(root)
    assert re.search(r"file-000\.mp4: 11 video frames, but the data has 17 rows", message)
    assert "\n" not in message


def test_row_count_must_match_info(tmp_path):
    root, _ = _dataset(tmp_path)
    info = json.loads((root / "meta/info.json").read_text())
    info["total_frames"] = 99
    (root / "meta/info.json").write_text(json.dumps(info))
    message = _rejection(root)
    assert re.search("17 rows, but meta/info.json says total_frames=99", message)
    assert "\n" not in message


def test_dataset_info_cli_prints_summary_and_one_line_errors(tmp_path):
    from typer.testing import CliRunner

    from toddlerbot.cli.main import app

    root, _ = _dataset(tmp_path)
    result = CliRunner().invoke(app, ["manip", "dataset", "info", str(root), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert (summary["episodes"], summary["frames"], summary["state_dim"]) == (2, 17, 2)
    (root / DATA_FILE).write_bytes(b"PAR1")
    result = CliRunner().invoke(app, ["manip", "dataset", "info", str(root)])
    assert isinstance(result.exception, DatasetError)
    assert "file-000.parquet" in str(result.exception)


def test_decoded_copy_round_trips_and_trains_without_the_reader(tmp_path):
    from toddlerbot.datasets.dataset import load_decoded, save_decoded
    from toddlerbot.dp.data import open_window_dataset

    root, _ = _dataset(tmp_path)
    ds = load_dataset(root)
    copy = load_decoded(save_decoded(ds, tmp_path / "ds.npz"))
    for name in ("state", "action", "timestamp", "episode_index", "images", "episode_bounds"):
        np.testing.assert_array_equal(getattr(copy, name), getattr(ds, name))
    assert copy.names == list(NAMES) and copy.tasks == ds.tasks and copy.summary() == ds.summary()
    from_dir, from_npz = open_window_dataset(root, 2, 4), open_window_dataset(tmp_path / "ds.npz", 2, 4)
    assert len(from_dir) == len(from_npz) == 17
    for key in ("observation.state", "action", "observation.images.head", "action_is_pad"):
        np.testing.assert_array_equal(from_dir[12][key], from_npz[12][key])
    assert from_npz.state_names == NAMES


def test_decoded_copy_rejects_foreign_and_inconsistent_files(tmp_path):
    from toddlerbot.datasets.dataset import load_decoded, save_decoded

    root, _ = _dataset(tmp_path)
    ds = load_dataset(root)
    np.savez(tmp_path / "foreign.npz", state=np.zeros((3, 2)))
    with pytest.raises(DatasetError) as err:
        load_decoded(tmp_path / "foreign.npz")
    assert "foreign.npz: missing array(s) meta, action" in str(err.value)
    save_decoded(ds, tmp_path / "ok.npz")
    with np.load(tmp_path / "ok.npz") as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["episode_bounds"] = np.array([[0, 11], [12, 17]])
    np.savez(tmp_path / "gap.npz", **arrays)
    with pytest.raises(DatasetError) as err:
        load_decoded(tmp_path / "gap.npz")
    assert "gap.npz: episode_bounds do not tile rows 0..17" in str(err.value)


def test_a_gathered_batch_equals_the_samples_cut_one_by_one(tmp_path):
    torch = pytest.importorskip("torch")
    from toddlerbot.dp.data import collate, gather, open_window_dataset, split_by_episode

    root, _ = _dataset(tmp_path)
    windows = open_window_dataset(root, 2, 4)
    train, _, _ = split_by_episode(windows, 0.5, seed=0)
    picks = [len(train) - 1, 0, 3, 3]  # an episode's last frame (padded actions) and a repeat
    keys = ("observation.state", "action", "action_is_pad", "observation.images.head")
    gathered = gather(train, picks, keys)
    one_by_one = collate([train[i] for i in picks], keys)
    for key in keys:
        assert gathered[key].dtype == one_by_one[key].dtype
        assert torch.equal(gathered[key], one_by_one[key])
    assert gathered["action_is_pad"][0].sum() == 3  # the last frame of its episode: 3 of 4 actions padded


def test_dataset_decode_command_writes_the_copy_and_refuses_another_suffix(tmp_path):
    from typer.testing import CliRunner

    from toddlerbot.cli.main import app
    from toddlerbot.datasets.dataset import load_decoded
    from toddlerbot.errors import ToddlerbotError

    root, _ = _dataset(tmp_path)
    result = CliRunner().invoke(app, ["manip", "dataset", "decode", str(root), "-o", str(tmp_path / "d.npz")])
    assert result.exit_code == 0, result.output
    assert "2 episodes, 17 frames" in result.output
    np.testing.assert_array_equal(load_decoded(tmp_path / "d.npz").images, load_dataset(root).images)
    refused = CliRunner().invoke(app, ["manip", "dataset", "decode", str(root), "-o", str(tmp_path / "d.zip")])
    assert isinstance(refused.exception, ToddlerbotError) and "expected a file name ending in .npz" in str(
        refused.exception)
    assert not (tmp_path / "d.zip").exists()
