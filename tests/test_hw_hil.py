"""Hardware in the loop: the `stand` policy runs through the runner, the real-robot backend and driver, and the
CLI emulator (own process, MuJoCo robot, real time) for a few seconds, and the robot stays standing."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.hardware.calibration import load_calibration
from toddlerbot.hardware.real_robot import RealRobot
from toddlerbot.policies import make_policy
from toddlerbot.robot.builder import build_model
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import load_spec
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import run_policy
from toddlerbot.runtime.tracking import TRACKING_BARS

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

port_handler = pytest.importorskip("dynamixel_sdk.port_handler")
SRC = Path(__file__).resolve().parents[1] / "src"


def _start_emulator(*args: str) -> tuple[subprocess.Popen, str]:
    env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    # started with SIGINT ignored, as a shell starts a background job: the emulator must still stop on it
    proc = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", "hw", "emulate", *args],
                            stdout=subprocess.PIPE, text=True, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    path = proc.stdout.readline().strip()
    assert path.startswith("/dev/"), f"emulator printed {path!r}"
    return proc, path


def _stop_emulator(proc: subprocess.Popen) -> dict:
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=20)
    return json.loads(out.strip().splitlines()[-1])


@pytest.mark.slow
def test_stand_policy_through_driver_emulator_and_simulation(tmp_path, monkeypatch):
    monkeypatch.setattr(port_handler, "LATENCY_TIMER", 50)  # ~100 ms status timeout: CI machines are loaded
    spec = load_spec()
    cal_file = tmp_path / "emulated.yaml"
    proc, path = _start_emulator("--hil", "--write-calibration", str(cal_file))
    try:
        cal = load_calibration(cal_file, RobotDescription(spec))
        with RealRobot(RobotDescription(spec), path, cal, control_dt=0.02, reset_duration=0.4, retries=5) as robot:
            home = robot.description.home_motor_pos
            result = run_policy(robot, make_policy("stand", robot), CommandSchedule.parse("0:0,0,0"), 3.0)
        errors = np.abs(result.log.motor_pos - home).max(axis=1)
    finally:
        report = _stop_emulator(proc)
    home_z = build_model(spec, scene=True).key("home").qpos[2]
    assert report["sim_time"] > 2.0 and report["realtime_factor"] > 0.5
    # while powered (torque off at the end lets the robot fall, as the real one would)
    assert report["powered_min_torso_upright"] > 0.97  # upright
    assert report["powered_min_torso_height"] > home_z - 0.03  # standing: sagged by less than 3 cm
    assert np.median(errors) < 0.05  # motors track the home pose within 3 degrees
    assert len(errors) == 150 and result.completed  # 3 s at 50 Hz


def test_motion_capture_from_an_emulator_without_a_body_is_one_line_before_torque(tmp_path):
    cal_file, log_file = tmp_path / "emulated.yaml", tmp_path / "run.npz"
    proc, path = _start_emulator("--write-calibration", str(cal_file))  # no --hil: no IMU, no pose
    try:
        run = _hw_run(path, cal_file, "--imu", "none", "--mocap", "emulator", "--policy", "stand", "--seconds", "1",
                      "--log", str(log_file), timeout=60)
    finally:
        report = _stop_emulator(proc)
    assert run.returncode == 2, run.stdout + run.stderr
    lines = [line for line in (run.stdout + run.stderr).splitlines() if line.strip()]
    assert len(lines) == 1 and "no emulated motion capture at" in lines[0], lines
    assert report["packets"] == 0 and not log_file.exists()  # refused before a byte reached the bus


def test_hw_run_cli_drives_a_policy_through_the_emulator(tmp_path):
    cal_file, log_file = tmp_path / "emulated.yaml", tmp_path / "run.npz"
    proc, path = _start_emulator("--write-calibration", str(cal_file))
    try:
        env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
        run = subprocess.run(
            [sys.executable, "-m", "toddlerbot.cli.main", "hw", "run", "--port", path, "--calibration", str(cal_file),
             "--imu", "none", "--policy", "replay", "--motion", "wave", "--seconds", "1", "--log", str(log_file)],
            capture_output=True, text=True, env=env, timeout=120,
        )
    finally:
        _stop_emulator(proc)
    assert run.returncode == 0, run.stderr
    assert "replay: 50 steps" in run.stdout
    from toddlerbot.runtime.log import RunLog

    log = RunLog.load(log_file)
    assert log.motor_target.shape == (50, 30)
    assert np.ptp(log.motor_target, axis=0).max() > 0.1  # the wave really moved a motor


def _hw_run(port: str, cal_file: Path, *args: str, timeout: float = 180) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    return subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", "hw", "run", "--port", port, "--calibration",
                           str(cal_file), "--latency-ms", "50", *args], capture_output=True, text=True, env=env,
                          timeout=timeout)


_, LINEAR_BAR, ANGULAR_BAR = TRACKING_BARS  # 0.024 m/s, 0.084 rad/s
HIL_TRACKING_BOUNDS = {"walk-rl": (0.16, LINEAR_BAR, ANGULAR_BAR), "walk-zmp": (0.16, 0.032, ANGULAR_BAR)}
"""Position (m), linear (m/s) and angular velocity (rad/s) errors a HIL walk stays within. walk-rl: issue 19's
1.5 x the appendix's Table 7 sim errors for the velocities (HIL 0.009-0.010 m/s, 0.026-0.028 rad/s), and for the
position the simulator's 0.123 m bar plus what the loop's delays cost (`benchmarks/bench_hil_like.py`), so that a
loaded CI machine passes (HIL 0.051-0.064 m). walk-zmp, the same but 0.032 m/s: HIL 0.016 m/s quiet and 0.021 beside
two busy loops (docs/hardware.md). walk-zmp's case is an expected, non-strict failure for now
(`WALK_ZMP_IN_REAL_TIME`): it keeps running and reports, and the bar stays the bar."""


WALK_ZMP_IN_REAL_TIME = pytest.mark.xfail(strict=False, reason=(
    "walk-zmp is marginal in real-time HIL on a 2-core VM: on 2026-11-29 it failed 1 of 3 runs at this code, 1 of 3 "
    "at e869420 and 2 of 5 at 5dd40f0 (which passed 10 of 10 on 2026-11-28): a fall at 6.7 s, yaw-rate errors of "
    "0.097-0.153 rad/s; a controller defect that issue 42's walk-zmp work owes (docs/hardware.md)"))


@pytest.mark.slow
@pytest.mark.parametrize("policy", ["walk-rl", pytest.param("walk-zmp", marks=WALK_ZMP_IN_REAL_TIME)])
def test_walking_policies_walk_the_tracking_schedule_in_real_time_on_the_emulated_imu(tmp_path, policy):
    """The whole stack a real walk uses: the policy reads the simulated IMU as the BNO08x reports it (100 Hz, 5 ms
    old) and drives the emulated bus through the driver and the safety layer (slew limit included), in real time.
    walk-zmp fell here after 3-23 s until the slew limit stopped clipping its knees and its forward capture-point
    gain was lowered for the loop's delays (docs/hardware.md)."""
    from toddlerbot.runtime.log import RunLog
    from toddlerbot.runtime.summary import summarize
    from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS

    cal_file, log_file = tmp_path / "emulated.yaml", tmp_path / "run.npz"
    proc, path = _start_emulator("--hil", "--write-calibration", str(cal_file))
    try:
        run = _hw_run(path, cal_file, "--imu", "emulator", "--mocap", "emulator", "--log", str(log_file), "--policy",
                      policy, "--command", DEFAULT_COMMANDS, "--seconds", str(DEFAULT_SECONDS))
    finally:
        report = _stop_emulator(proc)
    seen = f"{run.stdout}{run.stderr}emulator: {report}"  # what a failure on another machine needs to be read
    assert run.returncode == 0, seen
    assert report["powered_min_torso_upright"] > 0.9, seen  # walked upright all the way (a fall reads < 0.54)
    assert report["imu_reports"] > 50 * DEFAULT_SECONDS, seen  # the policy had its IMU (100 reports/s when unloaded)
    motion = report["powered_torso_motion"]
    moved = np.hypot(motion["dx_m"], motion["dy_m"])
    if policy == "walk-rl":
        # with its heading hold: simulator 0.92 m away (dx 0.56, dy 0.73), 1.97 rad; HIL 1.11 m, 1.94 rad. Without
        # the hold its turn followed the loop's timing (1.43-1.49 rad in HIL, 4.2-4.4 at 3 x the delays); with it
        # benchmarks/bench_hil_like.py turns 1.84-2.00 rad with up to 2 x HIL's delays, 1.79-1.91 at 3 x
        assert moved > 0.6 and abs(motion["yaw_rad"] - 2.0) < 0.4, seen
    else:  # simulator: 0.91 m away (dx 0.67, dy 0.61), 2.01 rad; three HIL runs: 0.84-0.89 m, 1.99-2.00 rad
        assert moved > 0.6 and abs(motion["yaw_rad"] - 2.0) < 0.3, seen
    # motion capture watched the walk: the tracking errors as `eval tracking` computes them in the simulator
    summary = summarize(RunLog.load(log_file), fell=False, fall_time=None)
    tracked = summary.tracking
    assert f"{policy} by motion capture: displacement" in run.stdout, seen
    assert np.hypot(*summary.displacement_m) == pytest.approx(moved, abs=0.05), seen  # the ramp moves it a little
    position, linear, angular = HIL_TRACKING_BOUNDS[policy]
    assert tracked.position_m < position and tracked.lin_vel_mps < linear, (tracked, seen)
    assert tracked.ang_vel_radps < angular, (tracked, seen)


ROUGH_1CM = "rough:height=0.01,cell=0.1"
"""CI's HIL terrain: tiles up to 1 cm (issue 42's HIL benchmark walks 2 cm, `benchmarks/bench_hil_walk.py`)."""
TERRAIN_POLICY_AT_TILE_EDGES = pytest.mark.xfail(strict=False, reason=(
    "the terrain policy (walk_rl_terrain.npz, trained on 1 cm tiles) stalls or falls at the first tile edges when it "
    "walks off the flat start square at 0.1 m/s (simulator, seeds 0-4: 4 falls; HIL, seed 0: upright in 3 runs, but "
    "short of 0.4 m out in 2 and 0.041 m/s off its command in the third), and the flat-floor default falls there: "
    "issue 42 still owes this walk (docs/hardware.md, \"Walking on rough ground in HIL\")"))


@pytest.mark.slow
@TERRAIN_POLICY_AT_TILE_EDGES
def test_walk_rl_walks_onto_1_cm_rough_ground_in_real_time(tmp_path):
    """`hw emulate --hil --terrain`: walk-rl's terrain policy, through the driver and the safety layer on the
    emulated IMU, walks 7 s at 0.1 m/s off the flat start square onto tiles up to 1 cm, upright, and motion capture
    tracks it within the flat floor's HIL bounds."""
    from toddlerbot.runtime.log import RunLog
    from toddlerbot.runtime.summary import summarize
    from toddlerbot.sim.terrain import START

    cal_file, log_file = tmp_path / "emulated.yaml", tmp_path / "run.npz"
    proc, path = _start_emulator("--hil", "--write-calibration", str(cal_file), "--terrain", ROUGH_1CM,
                                 "--terrain-seed", "0")
    try:
        run = _hw_run(path, cal_file, "--imu", "emulator", "--mocap", "emulator", "--log", str(log_file), "--policy",
                      "walk-rl", "--weights", "walk_rl_terrain", "--command", "0:0,0,0; 1:0.1,0,0", "--seconds", "8")
    finally:
        report = _stop_emulator(proc)
    seen = f"{run.stdout}{run.stderr}emulator: {report}"
    assert report["ground"] == f"{ROUGH_1CM} (seed 0)", seen
    assert run.returncode == 0 and report["powered_min_torso_upright"] > 0.9, seen  # no fall, upright all the way
    assert report["powered_torso_motion"]["dx_m"] > START + 0.15, seen  # its feet walked on the tiles
    tracked = summarize(RunLog.load(log_file), fell=False, fall_time=None).tracking
    position, linear, angular = HIL_TRACKING_BOUNDS["walk-rl"]
    assert tracked.position_m < position and tracked.lin_vel_mps < linear, (tracked, seen)
    assert tracked.ang_vel_radps < angular, (tracked, seen)


TOPPLE = """name: topple
description: tip backwards onto the floor
interpolation: smooth
joints: [left_ankle_pitch, right_ankle_pitch]
keyframes:
  - {t: 0.0, left_ankle_pitch: -21.7, right_ankle_pitch: 21.7}
  - {t: 0.5, left_ankle_pitch: 30, right_ankle_pitch: -30}
  - {t: 3.0, left_ankle_pitch: 30, right_ankle_pitch: -30}
"""


def test_a_fall_seen_by_the_imu_stops_hw_run_with_exit_code_1(tmp_path):
    cal_file, motion, log_file = tmp_path / "emulated.yaml", tmp_path / "topple.yaml", tmp_path / "run.npz"
    motion.write_text(TOPPLE)
    proc, path = _start_emulator("--hil", "--write-calibration", str(cal_file))
    try:
        run = _hw_run(path, cal_file, "--imu", "emulator", "--policy", "replay", "--motion", str(motion), "--seconds",
                      "3", "--log", str(log_file))
    finally:
        report = _stop_emulator(proc)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "replay: fell at" in run.stdout and "torque is off" in run.stdout
    from toddlerbot.runtime.log import RunLog

    steps = RunLog.load(log_file).time.size
    assert 10 < steps < 100  # stopped soon after tipping over (0.5 s in simulation), not after 3 s
    assert report["powered_min_torso_upright"] < 0.6  # it really fell


def test_walking_policies_refuse_to_run_without_an_imu(tmp_path):
    cal_file = tmp_path / "emulated.yaml"
    proc, path = _start_emulator("--write-calibration", str(cal_file))
    try:
        run = _hw_run(path, cal_file, "--imu", "none", "--policy", "walk-zmp")
    finally:
        report = _stop_emulator(proc)
    assert run.returncode == 2 and run.stderr.strip().count("\n") == 0, run.stderr
    assert "policy walk-zmp balances from the IMU: --imu none would run it blind" in run.stderr
    assert report["packets"] == 0  # refused before the bus was touched


@pytest.mark.slow
@pytest.mark.parametrize(("degrees", "side"), [(0, "front"), (180, "back")])
def test_a_walk_knocked_over_in_hil_gets_up_and_walks_on(tmp_path, degrees, side):
    """`hw run --on-fall get-up` through the driver: the HIL robot walking with walk-rl is kicked forwards or
    backwards (1.5 m/s, `hw emulate --kick`), falls onto that side, the get-up policy stands it up from the IMU alone
    (rolling from the back onto the front first) and walk-rl walks on to the end of the run (exit 0), upright."""
    from toddlerbot.policies.lying import lying_on
    from toddlerbot.robot.fall import FALL_TILT_RAD, tilt
    from toddlerbot.runtime.log import RunLog

    cal_file, log_file = tmp_path / "emulated.yaml", tmp_path / "run.npz"
    proc, path = _start_emulator("--hil", "--write-calibration", str(cal_file), "--kick", f"2:1.5@{degrees}")
    try:
        run = _hw_run(path, cal_file, "--imu", "emulator", "--policy", "walk-rl", "--command", "0:0.05,0,0",
                      "--seconds", "25", "--on-fall", "get-up", "--log", str(log_file))
    finally:
        report = _stop_emulator(proc)
    seen = run.stdout + run.stderr
    assert len(report["kicks"]) == 1 and report["powered_min_torso_upright"] < 0.5, seen  # it did go down
    log = RunLog.load(log_file)
    recovering = log.recovering.astype(bool)
    assert lying_on(log.imu_quat[np.flatnonzero(recovering)[0] + 50], upright_at=0.9) == side, seen  # 1 s after
    assert run.returncode == 0 and "walk-rl: 1 falls, got up from 1" in run.stdout, seen
    walking_on = log.time > log.time[recovering].max()
    assert 2.0 < recovering.sum() * log.control_dt < 15.0  # the get-up's own time, within its 3 attempts
    assert walking_on.sum() * log.control_dt > 5.0  # walked on for the rest of the run...
    assert max(tilt(q) for q in log.imu_quat[walking_on]) < FALL_TILT_RAD / 2  # ...upright
