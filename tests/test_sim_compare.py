"""`toddlerbot sim compare`: a log recorded by `hw run` against the hardware-in-the-loop emulator replays in the
simulator close to what it logged; simulating motors with other parameters shows up as a larger error."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from toddlerbot.cli.main import app
from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.runner import run_policy
from toddlerbot.runtime.sim_compare import CompareError, replay_in_sim
from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig

pytest.importorskip("dynamixel_sdk")
SRC = Path(__file__).resolve().parents[1] / "src"
ENV = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")


def _compare(*args: str) -> dict:
    result = CliRunner().invoke(app, ["sim", "compare", *args, "--json"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def _weaker_motors(path: Path) -> list[str]:
    """--motor-params options: params.json files of every motor model of the robot with half the torque and
    stiffness, a third of the powered damping."""
    description = RobotDescription.load()
    files = []
    for model in {m.name: m for m in description.motor_models}.values():
        a = model.actuator
        body = {"motor": model.name, "actuator": {"tau_max": 0.5 * a.tau_max, "tau_q_dot_max": 0.5 * a.tau_q_dot_max,
                                                  "kd_min": a.kd_min / 3, "kp_scale": 2 * a.kp_scale}}
        (path / f"{model.name}.json").write_text(json.dumps(body))
        files += ["--motor-params", str(path / f"{model.name}.json")]
    return files


def test_a_simulated_log_replays_exactly_and_walking_reports_table7(tmp_path: Path) -> None:
    description = RobotDescription.load()
    robot = MuJoCoRobot(description, SimConfig(control_dt=0.02))
    log = run_policy(robot, make_policy("walk-zmp", robot), CommandSchedule.parse("0:0.1,0,0"), 2.0).log
    assert log.motor_kp is not None and np.any(log.motor_kp != description.default_kp)  # walk-zmp changes gains
    path = log.save(tmp_path / "walk.npz")
    same = _compare(str(path))
    assert same["position_mae_deg"] < 1e-9 and same["gains_logged"]  # the simulator is deterministic
    assert same["tracking"]["sim"] == pytest.approx(same["tracking"]["real"])
    assert same["tracking"]["sim"]["lin_vel_mps"] < 0.1
    weaker = _compare(str(path), *_weaker_motors(tmp_path))
    assert weaker["position_mae_deg"] > 0.5
    with pytest.raises(CompareError, match="not this robot's"):
        replay_in_sim(RunLog(**{**log.__dict__, "motor_names": log.motor_names[:-1]}), description)


@pytest.mark.slow
@pytest.mark.realtime
def test_hw_run_log_from_the_hil_emulator_agrees_with_the_simulator(tmp_path: Path) -> None:
    cal, log_file = tmp_path / "emulated.yaml", tmp_path / "hil.npz"
    emulator = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", "hw", "emulate", "--hil",
                                 "--write-calibration", str(cal)], stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        device = emulator.stdout.readline().strip()
        assert device.startswith("/dev/"), device
        run = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", "hw", "run", "--port", device,
                              "--calibration", str(cal), "--imu", "none", "--policy", "replay", "--motion", "wave",
                              "--seconds", "3", "--log", str(log_file)],
                             capture_output=True, text=True, env=ENV, timeout=180)
    finally:
        emulator.send_signal(signal.SIGINT)
        emulator.communicate(timeout=30)
    assert run.returncode == 0, run.stderr
    real = _compare(str(log_file), "--plot", str(tmp_path / "plots"))
    weaker = _compare(str(log_file), *_weaker_motors(tmp_path))
    print(f"HIL vs sim: {real['position_mae_deg']:.3f} deg; weaker motors: {weaker['position_mae_deg']:.3f} deg")
    assert real["position_mae_deg"] < 1.0
    assert weaker["position_mae_deg"] > 1.5 * real["position_mae_deg"]
    assert (tmp_path / "plots" / "sim_vs_real.png").stat().st_size > 10_000
