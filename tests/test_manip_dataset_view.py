"""`toddlerbot manip dataset view`: a small dataset written, shown as a Rerun recording, and the recording read back:
camera frames, follower state and leader action per joint, episode boundaries and success."""

from __future__ import annotations

import re
import sys

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow")
pytest.importorskip("av")
pytest.importorskip("rerun")

from rerun.chunk import RrdReader  # noqa: E402

from toddlerbot.datasets.episode import RawEpisode, resample  # noqa: E402
from toddlerbot.datasets.lerobot_writer import write_dataset  # noqa: E402

NAMES = ("left_shoulder_pitch", "left_gripper")


def _raw(seconds: float, offset: float, success: bool) -> RawEpisode:
    """50 Hz ramps (state = t + offset, action = 2 t), images whose red channel encodes their index."""
    t = np.arange(round(seconds * 50) + 1) / 50
    images = np.zeros((len(t), 96, 96, 3), np.uint8)
    images[..., 0] = (np.arange(len(t)) * 4 % 256)[:, None, None]
    return RawEpisode("pick up the cube", NAMES, t, np.stack([t + offset, -t], 1), np.stack([2 * t, t], 1), t,
                      images, success=success)


@pytest.fixture
def dataset_root(tmp_path):
    raws = [_raw(1.0, 0.0, True), _raw(0.5, 1.0, False)]
    return write_dataset(tmp_path / "ds", [resample(r, 10) for r in raws], NAMES, 10, raw_episodes=raws)


def _run(args, capsys):
    from toddlerbot.cli.main import main

    sys.argv = ["toddlerbot", *args]
    with pytest.raises(SystemExit) as exit_info:
        main()
    out = capsys.readouterr()
    return exit_info.value.code, out.out, out.err


def _columns(path):
    """{entity: {column: [values per row, in time order]}} of the recording's temporal chunks."""
    out: dict[str, dict[str, list]] = {}
    for chunk in RrdReader(path).stream().collect().stream():
        if chunk.is_static:
            continue
        record = chunk.to_record_batch()
        batch = {name: (col.cast(pa.int64()) if pa.types.is_temporal(col.type) else col).to_pylist()
                 for name, col in zip(record.schema.names, record.columns)}  # times as int ns
        order = np.argsort(batch["time"], kind="stable")
        entity = out.setdefault(chunk.entity_path, {})
        for name, values in batch.items():
            entity.setdefault(name, []).extend(values[i] for i in order)
    return out


def test_recording_holds_camera_joints_boundaries_and_success(dataset_root, tmp_path, capsys):
    rrd = tmp_path / "view.rrd"
    code, out, _ = _run(["manip", "dataset", "view", str(dataset_root), "--save", str(rrd)], capsys)
    assert code == 0 and "2 episode(s), 17 frames (1.7 s); success 0: yes, 1: no" in out
    rec = _columns(rrd)

    # time runs 0..1.6 s over both episodes; frame is the dataset row
    state = rec["/joints/left_shoulder_pitch/state"]
    assert len(state["time"]) == 17
    np.testing.assert_allclose(np.array(state["time"]) / 1e9, np.arange(17) / 10)  # stored in ns
    np.testing.assert_allclose(np.concatenate(state["Scalars:scalars"]),
                               np.r_[np.arange(11) / 10, 1 + np.arange(6) / 10], atol=1e-6)
    action = rec["/joints/left_gripper/action"]
    np.testing.assert_allclose(np.concatenate(action["Scalars:scalars"]), np.r_[np.arange(11), np.arange(6)] / 10,
                               atol=1e-6)

    # the head camera: one 96x96 image per row; the red channel's index code survives the video
    images = rec["/camera/head"]["Image:buffer"]
    assert len(images) == 17
    red = [np.asarray(b[0], np.uint8).reshape(96, 96, 3)[40:56, 40:56, 0].mean() for b in images]
    expected = np.r_[np.arange(0, 51, 5), np.arange(0, 26, 5)] * 4  # 10 Hz rows of 50 Hz images
    assert np.max(np.abs(np.array(red) - expected)) < 3

    # boundaries: the episode index steps at row 11; success 1 then 0; one log line per episode at its start
    np.testing.assert_array_equal(np.concatenate(rec["/episode/index"]["Scalars:scalars"]), [0] * 11 + [1] * 6)
    np.testing.assert_array_equal(np.concatenate(rec["/episode/success"]["Scalars:scalars"]), [1] * 11 + [0] * 6)
    log = rec["/episodes"]
    assert np.array(log["time"]).tolist() == [0, int(1.1e9)]
    assert log["TextLog:text"][0][0].startswith("episode 0: 11 frames (1.1 s), task 'pick up the cube', success: yes")
    assert log["TextLog:text"][1][0].endswith("success: NO")


def test_one_episode_and_bad_input(dataset_root, tmp_path, capsys):
    rrd = tmp_path / "one.rrd"
    code, out, _ = _run(["manip", "dataset", "view", str(dataset_root), "--episode", "1", "--save", str(rrd)], capsys)
    assert code == 0 and "1 episode(s), 6 frames (0.6 s); success 1: no" in out
    rec = _columns(rrd)
    np.testing.assert_array_equal(rec["/joints/left_shoulder_pitch/state"]["frame"], np.arange(11, 17))
    np.testing.assert_allclose(np.concatenate(rec["/joints/left_shoulder_pitch/state"]["Scalars:scalars"]),
                               1 + np.arange(6) / 10, atol=1e-6)
    size_kb = rrd.stat().st_size / 1e3
    assert size_kb < 200, size_kb

    code, _, err = _run(["manip", "dataset", "view", str(dataset_root), "--episode", "2", "--save", str(rrd)], capsys)
    assert code == 2 and "--episode 2: the dataset has episodes 0-1" in err and len(err.strip().splitlines()) == 1
    code, _, err = _run(["manip", "dataset", "view", str(dataset_root), "--save", str(tmp_path / "x.mp4")], capsys)
    assert code == 2 and "expected a file name ending in .rrd" in err
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        taken = busy.getsockname()[1]
        code, _, err = _run(["manip", "dataset", "view", str(dataset_root), "--web", "--port", str(taken - 1)], capsys)
    assert code == 2 and re.search(rf"port ({taken - 1}|{taken}) is not free", err), err



def _free_port() -> int:
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class _Recording:
    def connect_grpc(self, url):
        self.url = url


@pytest.mark.parametrize(("user", "viewer_ci"), [({}, "1"), ({"CI": "true"}, "true"),
                                                 ({"FORCE_RERUN_ANALYTICS": "1"}, "1")])
def test_the_viewer_we_start_has_analytics_off_unless_the_user_said(monkeypatch, user, viewer_ci):
    import os
    import subprocess

    from toddlerbot.datasets import view

    for name in ("CI", "FORCE_RERUN_ANALYTICS"):
        monkeypatch.delenv(name, raising=False)
    for name, value in user.items():
        monkeypatch.setenv(name, value)
    port = _free_port()
    monkeypatch.setattr(view, "VIEWER_PORT", port)
    started = []
    monkeypatch.setattr(subprocess, "Popen", lambda args, **kwargs: started.append((args, kwargs)))
    recording = _Recording()
    view.spawn_viewer(recording)
    (args, kwargs), = started
    assert args[1:] == ["-m", "rerun_cli", f"--port={port}", "--expect-data-soon"]
    assert kwargs["env"]["CI"] == viewer_ci and kwargs["env"]["RERUN_APP_ONLY"] == "true"
    assert kwargs["env"].get("FORCE_RERUN_ANALYTICS") == user.get("FORCE_RERUN_ANALYTICS")  # an opt-in passes on
    assert kwargs["start_new_session"]  # a Ctrl-C in the terminal leaves the viewer open
    assert os.environ.get("CI") == user.get("CI")  # our own environment is left as it was
    assert recording.url == f"rerun+http://127.0.0.1:{port}/proxy"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the viewer must fail to open a window (no display)")
def test_the_real_viewer_queues_no_analytics(tmp_path):
    """Rerun's viewer, started as `manip dataset view` starts it, with a fresh home folder and no display: it starts
    (and stops at the missing display) without writing an analytics session file, the queue it uploads from."""
    import os
    import subprocess

    env = {name: value for name, value in os.environ.items()
           if name not in ("CI", "FORCE_RERUN_ANALYTICS", "DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")}
    env |= {"HOME": str(tmp_path), "XDG_CONFIG_HOME": str(tmp_path / "config"), "XDG_DATA_HOME": str(tmp_path / "data")}
    script = ("from toddlerbot.datasets import view\n"  # streaming to the viewer is not under test: no recording
              "class Recording:\n    def connect_grpc(self, url): pass\n"
              f"view.VIEWER_PORT = {_free_port()}\nview.spawn_viewer(Recording())")
    # returns once the viewer, which shares our stderr, has exited
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=60)
    assert "DISPLAY" in result.stderr, result.stderr  # the viewer ran: winit found no display
    assert not list(tmp_path.rglob("analytics/*.json"))
