"""Run logs written in chunks: a recorder with a log file holds at most one chunk of rows, joins its chunks into the
same log as one that held everything, and a recorder killed mid-run leaves chunks that load with every complete
row."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.errors import ToddlerbotError
from toddlerbot.runtime.log import LogRecorder, RunLog, parts_of

SRC = Path(__file__).resolve().parents[1] / "src"
NAMES = ("a", "b")


def _row(k: int) -> dict:
    """Step k of a made-up run: every value tells the step it came from."""
    v = np.array([k, -k], dtype=float)
    return dict(time=0.02 * k, command=np.full(3, 0.1), motor_pos=v, motor_vel=v + 1, motor_torque=v + 2,
                joint_pos=v + 3, joint_vel=v + 4, motor_target=v + 5, joint_target=v + 6,
                imu_quat=np.array([1.0, 0, 0, 0]), imu_ang_vel=np.full(3, k), imu_lin_acc=np.zeros(3),
                foot_contact=np.array([k % 2, 1 - k % 2], bool), base_pos=np.full(3, np.nan),
                base_quat=np.full(4, np.nan), compute_time=0.001 * k, step_period=0.02, motor_kp=v * 10,
                motor_kd=v)


def _assert_same(a: RunLog, b: RunLog) -> None:
    for f in fields(RunLog):
        np.testing.assert_array_equal(np.asarray(getattr(a, f.name)), np.asarray(getattr(b, f.name)), err_msg=f.name)


def test_a_recorder_with_a_log_file_holds_one_chunk_at_most_and_finishes_the_same_log(tmp_path):
    path = tmp_path / "run.npz"
    chunked, whole = LogRecorder(path, chunk_seconds=0.1), LogRecorder()  # 0.1 s at 50 Hz: chunks of 5 rows
    chunked.start(NAMES, NAMES, 0.02, "stand")
    held = []
    for k in range(23):
        chunked.append(**_row(k))
        whole.append(**_row(k))
        held.append(len(chunked.rows["time"]))
    assert max(held) == 4 and held[:6] == [1, 2, 3, 4, 0, 1]  # written to disk on the 5th row of each chunk
    assert len(chunked) == 23 and chunked.spilled == 20
    assert [p.name for p in sorted(parts_of(path).iterdir())] == [f"00000{i}.npz" for i in range(4)]
    log = chunked.finish(NAMES, NAMES, 0.02, "stand")
    _assert_same(log, whole.finish(NAMES, NAMES, 0.02, "stand"))  # the same arrays as a log held in memory
    assert log.time.size == 23 and log.motor_kd[-1, 1] == -22
    log.save(path)
    assert not parts_of(path).exists()  # the file holds the log now
    _assert_same(RunLog.load(path), log)


def test_a_recorder_killed_mid_run_leaves_chunks_that_load_with_every_complete_row(tmp_path):
    path = tmp_path / "run.npz"
    child = textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_run_log_chunks import NAMES, _row
        from toddlerbot.runtime.log import LogRecorder
        recorder = LogRecorder({str(path)!r}, chunk_seconds=0.1)
        recorder.start(NAMES, NAMES, 0.02, "stand")
        k = 0
        while True:
            recorder.append(**_row(k))
            k += 1
            time.sleep(0.002)
    """)
    env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    proc = subprocess.Popen([sys.executable, "-c", child], env=env)
    try:
        deadline = time.monotonic() + 60
        while len(list(parts_of(path).glob("[0-9]*.npz"))) < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    chunks = len(list(parts_of(path).glob("[0-9]*.npz")))
    (parts_of(path) / f".{chunks:06d}.npz.x1y2.npz").write_bytes(b"PK\x03\x04 half")  # a chunk cut off mid-write
    log = RunLog.load(path)  # no file yet: the chunks beside it
    assert chunks >= 3 and log.time.size == 5 * chunks  # every complete chunk, nothing else
    np.testing.assert_allclose(log.time, 0.02 * np.arange(5 * chunks))
    np.testing.assert_array_equal(log.motor_pos[:, 1], -np.arange(5 * chunks))
    assert log.motor_names == NAMES and log.policy == "stand" and log.control_dt == 0.02
    _assert_same(RunLog.load(parts_of(path)), log)  # the folder named itself
    with pytest.raises(ToddlerbotError, match="holds the chunks of an unfinished run logged to"):
        LogRecorder(path)  # a new run does not mix its chunks with these
    log.save(path)  # kept as a log: the documented recovery
    assert not parts_of(path).exists()
    _assert_same(RunLog.load(path), log)


def test_a_chunk_that_cannot_be_written_leaves_the_rows_in_memory_and_the_run_going(tmp_path):
    path = tmp_path / "run.npz"
    parts_of(path).write_text("in the way")  # the chunks' folder cannot be made, as on a full disk
    recorder = LogRecorder(path, chunk_seconds=0.1)
    recorder.start(NAMES, NAMES, 0.02, "stand")
    for k in range(12):
        recorder.append(**_row(k))
    assert recorder.spilled == 0 and len(recorder.rows["time"]) == 12 and recorder.parts is None
    np.testing.assert_allclose(recorder.finish(NAMES, NAMES, 0.02, "stand").time, 0.02 * np.arange(12))


def test_chunks_of_two_runs_or_none_at_all_are_one_line_errors(tmp_path):
    first, second = (LogRecorder(tmp_path / name, chunk_seconds=0.02) for name in ("a.npz", "b.npz"))
    first.start(NAMES, NAMES, 0.02, "stand")
    second.start(NAMES, NAMES, 0.02, "walk-rl")
    first.append(**_row(0))
    second.append(**_row(1))
    second.chunks[0].rename(first.chunks[0].with_name("000001.npz"))
    with pytest.raises(ToddlerbotError, match=r"a.npz.parts: chunk 1 differs from chunk 0 in policy: chunks of "):
        RunLog.load(tmp_path / "a.npz")
    with pytest.raises(ToddlerbotError, match=r"b.npz.parts: holds no chunk of a run log"):
        RunLog.load(tmp_path / "b.npz")


def test_sim_run_with_a_log_file_writes_a_chunk_every_10_s_and_saves_one_npz(tmp_path):
    from toddlerbot.sessions.sim import sim_session

    path = tmp_path / "run.npz"
    result = sim_session("stand", "0:0,0,0", 12.0).run(log_path=path)
    assert [p.name for p in parts_of(path).iterdir()] == ["000000.npz"]  # 500 steps on disk, 100 held
    assert RunLog.load(path).time.size == 500  # what a kill at this moment would have kept
    assert result.log.time.size == 600
    np.testing.assert_allclose(np.diff(result.log.time), 0.02, atol=1e-9)  # chunk and rows joined in order
    result.log.save(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]
    _assert_same(RunLog.load(path), result.log)
