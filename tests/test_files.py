"""Atomic file output: unique temporary names, nothing left on error, concurrent writers of one file never mix."""

from __future__ import annotations

import threading
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.files import atomic_savez, atomic_write, atomic_write_text, save_figure
from toddlerbot.runtime.log import RunLog


def test_atomic_write_leaves_nothing_on_error_and_keeps_the_old_content(tmp_path: Path) -> None:
    target = tmp_path / "out" / "params.json"
    atomic_write_text(target, "old")

    def fail(tmp: Path) -> None:
        tmp.write_text("half")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        atomic_write(target, fail)
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["params.json"]
    assert target.read_text() == "old"


def test_each_write_gets_its_own_temporary_file_beside_the_target(tmp_path: Path) -> None:
    seen: list[Path] = []
    for _ in range(3):
        atomic_write(tmp_path / "log.npz", lambda tmp: (seen.append(tmp), tmp.write_bytes(b"x")))
    assert len(set(seen)) == 3
    assert all(p.parent == tmp_path and p.suffix == ".npz" and p.name.startswith(".log.npz.") for p in seen)
    assert [p.name for p in tmp_path.iterdir()] == ["log.npz"]


def test_savez_writes_exactly_the_given_name_even_without_npz_suffix(tmp_path: Path) -> None:
    path = atomic_savez(tmp_path / "run.log", {"a": np.arange(3.0)}, compressed=True)
    assert [p.name for p in tmp_path.iterdir()] == ["run.log"]
    with np.load(path, allow_pickle=False) as data:
        np.testing.assert_array_equal(data["a"], [0.0, 1.0, 2.0])


def _run_log(steps: int, motors: int, value: float, policy: str) -> RunLog:
    shapes = {"time": (steps,), "command": (steps, 3), "imu_quat": (steps, 4), "imu_ang_vel": (steps, 3),
              "imu_lin_acc": (steps, 3), "foot_contact": (steps, 2), "base_pos": (steps, 3), "base_quat": (steps, 4),
              "compute_time": (steps,), "step_period": (steps,)}
    names = tuple(f"m{i}" for i in range(motors))
    extra = {"motor_names": names, "joint_names": names, "control_dt": 0.02, "policy": policy}
    arrays = {f.name: np.full(shapes.get(f.name, (steps, motors)), value)
              for f in fields(RunLog) if f.name not in extra}
    return RunLog(**arrays, **extra)


def test_two_runs_saving_the_same_log_leave_one_whole_log(tmp_path: Path) -> None:
    path = tmp_path / "walk.npz"
    logs = [_run_log(3000, 30, 1.0, "walk-zmp"), _run_log(2000, 30, 2.0, "stand")]

    def save(log: RunLog, start: threading.Barrier, errors: list[Exception]) -> None:
        start.wait()
        try:
            log.save(path)
        except Exception as exc:  # a failing writer is the bug this test pins
            errors.append(exc)

    for _ in range(5):
        start, errors = threading.Barrier(len(logs)), []
        threads = [threading.Thread(target=save, args=(log, start, errors)) for log in logs]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert errors == []
        back = RunLog.load(path)  # a whole log: one writer's, never a mix
        winner = logs[0] if back.policy == "walk-zmp" else logs[1]
        assert back.motor_pos.shape == winner.motor_pos.shape
        np.testing.assert_array_equal(back.joint_target, winner.joint_target)
        assert [p.name for p in tmp_path.iterdir()] == ["walk.npz"]


def test_save_figure_writes_the_laid_out_figure_and_closes_it(tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1], [0, 1])
    path = save_figure(fig, tmp_path / "plots" / "line.png", dpi=50)
    assert fig.number not in plt.get_fignums()
    with Image.open(path) as image:
        assert image.size == (200, 150)  # figsize x dpi
        pixels = np.asarray(image.convert("L"))
    assert (pixels < 128).mean() > 0.005  # the line and axes were drawn


def test_written_files_get_the_permissions_of_a_plain_open(tmp_path):
    import os
    import stat

    from toddlerbot.files import FILE_MODE, atomic_write_text

    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    written = atomic_write_text(tmp_path / "atomic.txt", "x")
    assert stat.S_IMODE(os.stat(written).st_mode) == stat.S_IMODE(os.stat(plain).st_mode) == FILE_MODE
