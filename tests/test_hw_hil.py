"""Hardware in the loop: the CLI emulator (own process, MuJoCo robot, real-time) driven through the real-robot
backend holds the home pose for a few seconds and the robot stays standing."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.hardware.calibration import load_calibration
from toddlerbot.hardware.real_robot import RealRobot, home_motor_angles
from toddlerbot.robot.builder import build_model
from toddlerbot.robot.spec import load_spec

port_handler = pytest.importorskip("dynamixel_sdk.port_handler")
SRC = Path(__file__).resolve().parents[1] / "src"


def _start_emulator(*args: str) -> tuple[subprocess.Popen, str]:
    env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    proc = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", "hw", "emulate", *args],
                            stdout=subprocess.PIPE, text=True, env=env)
    path = proc.stdout.readline().strip()
    assert path.startswith("/dev/"), f"emulator printed {path!r}"
    return proc, path


def _stop_emulator(proc: subprocess.Popen) -> dict:
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=20)
    return json.loads(out.strip().splitlines()[-1])


@pytest.mark.slow
def test_hold_home_through_driver_emulator_and_simulation(tmp_path, monkeypatch):
    monkeypatch.setattr(port_handler, "LATENCY_TIMER", 50)  # ~100 ms status timeout: CI machines are loaded
    spec = load_spec()
    cal_file = tmp_path / "emulated.yaml"
    proc, path = _start_emulator("--hil", "--write-calibration", str(cal_file))
    try:
        cal = load_calibration(cal_file, spec)
        with RealRobot(spec, path, cal, control_dt=0.02, reset_duration=0.4, retries=5) as robot:
            robot.reset()
            home = home_motor_angles(spec, robot)
            start, errors = time.perf_counter(), []
            while time.perf_counter() - start < 3.0:
                obs = robot.step(home)
                errors.append(np.abs(obs.motor_pos - home).max())
    finally:
        report = _stop_emulator(proc)
    home_z = build_model(spec, scene=True).key("home").qpos[2]
    assert report["sim_time"] > 2.0 and report["realtime_factor"] > 0.5
    # while powered (torque off at the end lets the robot fall, as the real one would)
    assert report["powered_min_torso_upright"] > 0.97  # upright
    assert report["powered_min_torso_height"] > home_z - 0.03  # standing: sagged by less than 3 cm
    assert np.median(errors) < 0.05  # motors track the home pose within 3 degrees
    assert len(errors) > 100  # about 50 Hz
