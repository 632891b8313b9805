"""A walking policy in hardware-in-the-loop against the simulator: the default tracking schedule (26 s) walked
by `hw run --imu emulator` through the driver, the safety layer and the emulated bus of `hw emulate --hil` (the
MuJoCo robot in real time, its IMU streamed as the BNO08x reports), and by the same policy in the simulator.
Printed per run: falls, where the torso ended (dx, dy in the start heading's frame), its yaw change and the tracking
errors `eval tracking` computes, in HIL from the emulator's motion capture (`hw run --mocap emulator`), so the two
are measured alike; then the emulator's `powered_torso_motion` (from the moment torque came on, the ramp to the pose
included), its real-time factor and IMU reports, wall time.

Run: PYTHONPATH=src python benchmarks/bench_hil_walk.py [--policy walk-zmp|walk-rl] [--weights FILE] [--runs N]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.runner import run_policy
from toddlerbot.runtime.summary import RunSummary, summarize
from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


def simulated(policy: str, weights: str | None) -> tuple[RunSummary, float]:
    """The policy's run in the simulator and its wall time, s."""
    robot = MuJoCoRobot(RobotDescription.load())
    start = time.perf_counter()
    result = run_policy(robot, make_policy(policy, robot, weights=weights), CommandSchedule.parse(DEFAULT_COMMANDS),
                        DEFAULT_SECONDS, stop_on_fall=True)
    return summarize(result.log, result.fell, result.fall_time), time.perf_counter() - start


def in_the_loop(policy: str, weights: str | None) -> dict:
    """One `hw run` against `hw emulate --hil`, watched by the emulator's motion capture: its summary from the run's
    log, exit code and last line, and the emulator's statistics."""
    cli = [sys.executable, "-m", "toddlerbot.cli.main"]
    with tempfile.TemporaryDirectory() as tmp:
        cal, log = Path(tmp) / "emulated.yaml", Path(tmp) / "run.npz"
        emulator = subprocess.Popen([*cli, "hw", "emulate", "--hil", "--write-calibration", str(cal)],
                                    stdout=subprocess.PIPE, text=True)
        try:
            port = emulator.stdout.readline().strip()
            start = time.perf_counter()
            run = subprocess.run([*cli, "hw", "run", "--port", port, "--calibration", str(cal), "--imu", "emulator",
                                  "--mocap", "emulator", "--log", str(log), "--policy", policy,
                                  *(["--weights", weights] if weights else []),
                                  "--command", DEFAULT_COMMANDS, "--seconds", str(DEFAULT_SECONDS)],
                                 capture_output=True, text=True, timeout=DEFAULT_SECONDS * 4 + 60)
            wall = time.perf_counter() - start
        finally:
            emulator.send_signal(signal.SIGINT)
            out, _ = emulator.communicate(timeout=30)
        run_log = RunLog.load(log) if log.is_file() else None
    report = json.loads(out.strip().splitlines()[-1])
    fell = run.returncode == 1
    return {"summary": None if run_log is None else summarize(run_log, fell, None), "exit": run.returncode,
            "report": report, "wall_s": wall,
            "last_line": run.stdout.strip().splitlines()[-1] if run.stdout.strip() else run.stderr.strip()[-200:]}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--policy", default="walk-zmp")
    parser.add_argument("--weights", default=None)
    parser.add_argument("--runs", type=int, default=1, help="HIL runs (each against a fresh emulator)")
    args = parser.parse_args()
    os.environ.setdefault("PYTHONPATH", str(Path(__file__).resolve().parents[1] / "src"))
    print(f"{args.policy} ({args.weights or 'default weights'}), schedule {DEFAULT_COMMANDS!r}, {DEFAULT_SECONDS} s; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    sim, wall = simulated(args.policy, args.weights)
    print(f"simulator: fell {sim.fell}, {sim.motion_text()} ({wall:.1f} s wall)")
    for _ in range(args.runs):
        hil = in_the_loop(args.policy, args.weights)
        report, motion = hil["report"], hil["report"]["powered_torso_motion"]
        print(f"HIL:       exit {hil['exit']}, by motion capture: "
              f"{hil['summary'].motion_text() if hil['summary'] else 'no log'}")
        print(f"           emulator (powered, the ramp included): dx {motion['dx_m']:.3f} m, "
              f"dy {motion['dy_m']:.3f} m, "
              f"yaw {motion['yaw_rad']:.3f} rad; real-time factor {report['realtime_factor']:.2f}, "
              f"{report['imu_reports']} IMU reports, min uprightness {report['powered_min_torso_upright']:.3f}, "
              f"{hil['wall_s']:.1f} s wall, load {os.getloadavg()[0]:.1f}")
        print(f"hw run: {hil['last_line']}")


if __name__ == "__main__":
    main()
