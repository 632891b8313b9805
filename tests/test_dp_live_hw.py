"""`hw run --policy dp` through the driver against the hardware-in-the-loop emulator: a tiny checkpoint trained
here, a short video file as the head camera; the run completes, every command stays in range, chunks are used,
and torque is off at the end."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from dp_live_support import GRIPPER, SPACE, write_video  # noqa: E402
from dp_support import SyntheticWindows  # noqa: E402
from hw_support import emulated  # noqa: E402
from toddlerbot.dp.config import TINY  # noqa: E402
from toddlerbot.dp.train import TrainSchedule, train  # noqa: E402
from toddlerbot.hardware.calibration import Calibration, save_calibration, spec_label  # noqa: E402
from toddlerbot.hardware.control_table import RAD_PER_PULSE, pulses_to_rad  # noqa: E402
from toddlerbot.runtime.log import RunLog  # noqa: E402

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

SRC = Path(__file__).resolve().parents[1] / "src"
ENV = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
LOW, HIGH = GRIPPER.motor_range.T


class PickLikeWindows(SyntheticWindows):
    """Synthetic windows on the pick task's 16 motors: states and actions within 0.3 rad of the home pose and
    inside the motors' ranges (the grippers' home is their range's end)."""

    def __init__(self) -> None:
        super().__init__(episodes=2, frames=8, state_dim=SPACE.dim, action_dim=SPACE.dim, image_size=96)
        self.state_names = self.action_names = SPACE.names
        self.home = GRIPPER.home_motor_pos[SPACE.indices].astype(np.float32)

    def __getitem__(self, i: int) -> dict:
        sample = super().__getitem__(i)
        lo, hi = LOW[SPACE.indices], HIGH[SPACE.indices]
        sample["observation.state"] = np.clip(self.home + 0.3 * sample["observation.state"], lo, hi).astype(np.float32)
        sample["action"] = np.clip(self.home + 0.1 * sample["action"], lo, hi).astype(np.float32)
        return sample


@pytest.mark.slow
def test_hw_run_dp_drives_the_gripper_robot_through_the_emulator(tmp_path):
    torch.set_num_threads(1)
    run = train(PickLikeWindows(), TINY, tmp_path / "run", schedule=TrainSchedule(max_steps=2), show_progress=False)
    video = write_video(tmp_path / "head.mp4", frames=80, fps=10)  # 8 s: outlasts the start-up and the run
    log_file = tmp_path / "run.npz"
    with emulated(GRIPPER, hil=True) as (emu, port):
        cal = tmp_path / "cal.yaml"
        save_calibration(Calibration("emulated", spec_label(GRIPPER), {m.name: m.mounting_offset
                                                                        for m in emu.motors}), cal)
        proc = subprocess.run(
            [sys.executable, "-m", "toddlerbot.cli.main", "hw", "run", "--port", port, "--calibration", str(cal),
             "--variant", "gripper", "--imu", "none", "--policy", "dp", "--checkpoint", str(run.checkpoint),
             "--camera", str(video), "--seconds", "2", "--latency-ms", "50", "--log", str(log_file)],
            capture_output=True, text=True, env=ENV, timeout=240)
        with emu.lock:
            powered = [m.name for m in emu.motors if m.torque_on]
            goals = pulses_to_rad([m.get("goal_position") - m.mounting_offset - m.turn_offset
                                   - m.get("homing_offset") for m in emu.motors])
    assert proc.returncode == 0, proc.stderr
    assert "dp: 100 steps" in proc.stdout  # 2 s at 50 Hz
    used = int(re.search(r"dp: (\d+) chunks used", proc.stdout).group(1))
    failed = int(re.search(r"(\d+) failed inferences", proc.stdout).group(1))
    assert used >= 2 and failed == 0, proc.stdout
    assert powered == []  # torque off at the end
    assert np.all(goals >= LOW - RAD_PER_PULSE) and np.all(goals <= HIGH + RAD_PER_PULSE)
    log = RunLog.load(log_file)
    targets = log.motor_target
    assert targets.shape == (100, GRIPPER.n_motors) and np.isfinite(targets).all()
    assert np.all(targets >= LOW) and np.all(targets <= HIGH)
    # the policy moved its motors (within the training actions' range around home) and held every other one
    moved = np.abs(targets[:, SPACE.indices] - GRIPPER.home_motor_pos[SPACE.indices]).max()
    assert 0.0 < moved < 0.5
    others = np.setdiff1d(np.arange(GRIPPER.n_motors), SPACE.indices)
    assert np.ptp(targets[:, others], axis=0).max() == 0.0


def test_hw_run_dp_refuses_a_bad_camera_or_a_gripper_checkpoint_on_the_default_robot_before_the_bus(tmp_path):
    run = train(PickLikeWindows(), TINY, tmp_path / "run", schedule=TrainSchedule(max_steps=1), show_progress=False)
    video = write_video(tmp_path / "head.mp4", frames=5)
    errors = []
    with emulated() as (emu, port):
        cal = tmp_path / "cal.yaml"
        save_calibration(Calibration("emulated", "toddlerbot_v1", {m.name: m.mounting_offset for m in emu.motors}),
                         cal)
        for camera in ("/nonexistent.mp4", str(video)):
            proc = subprocess.run(
                [sys.executable, "-m", "toddlerbot.cli.main", "hw", "run", "--port", port, "--calibration", str(cal),
                 "--imu", "none", "--policy", "dp", "--checkpoint", str(run.checkpoint), "--camera", camera],
                capture_output=True, text=True, env=ENV, timeout=120)
            lines = [line for line in proc.stderr.splitlines() if line.strip()]
            assert proc.returncode == 2 and len(lines) == 1, proc.stderr
            errors.append(lines[0])
        packets = emu.stats.packets_in
    assert "camera /nonexistent.mp4: cannot open" in errors[0]
    assert "state name(s) left_gripper_drive, right_gripper_drive are not motors of this robot" in errors[1]
    assert "--variant gripper" in errors[1]
    assert packets == 0  # refused before the bus was opened
