"""A walking policy in hardware-in-the-loop against the simulator: the default tracking schedule (26 s) walked
by `hw run --imu emulator` through the driver, the safety layer and the emulated bus of `hw emulate --hil` (the
MuJoCo robot in real time, its IMU streamed as the BNO08x reports), and by the same policy in the simulator.
Printed per run: falls, the torso's planar motion (dx, dy, yaw change: what motion capture would measure; for HIL
the emulator's `powered_torso_motion`), the emulator's real-time factor and IMU reports, wall time.

Run: PYTHONPATH=src python benchmarks/bench_hil_walk.py [--policy walk-zmp|walk-rl] [--weights FILE]
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

import numpy as np

from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import run_policy
from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS, heading
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


def simulated(policy: str, weights: str | None) -> dict:
    robot = MuJoCoRobot(RobotDescription.load())
    start = time.perf_counter()
    result = run_policy(robot, make_policy(policy, robot, weights=weights), CommandSchedule.parse(DEFAULT_COMMANDS),
                        DEFAULT_SECONDS, stop_on_fall=True)
    log = result.log
    yaw = np.unwrap(heading(np.asarray(log.base_quat)))
    moved = np.asarray(log.base_pos[-1]) - np.asarray(log.base_pos[0])
    return {"fell": result.fell, "dx_m": float(moved[0]), "dy_m": float(moved[1]), "yaw_rad": float(yaw[-1] - yaw[0]),
            "wall_s": time.perf_counter() - start}


def in_the_loop(policy: str, weights: str | None) -> dict:
    cli = [sys.executable, "-m", "toddlerbot.cli.main"]
    with tempfile.TemporaryDirectory() as tmp:
        cal = Path(tmp) / "emulated.yaml"
        emulator = subprocess.Popen([*cli, "hw", "emulate", "--hil", "--write-calibration", str(cal)],
                                    stdout=subprocess.PIPE, text=True)
        try:
            port = emulator.stdout.readline().strip()
            start = time.perf_counter()
            run = subprocess.run([*cli, "hw", "run", "--port", port, "--calibration", str(cal), "--imu", "emulator",
                                  "--policy", policy, *(["--weights", weights] if weights else []),
                                  "--command", DEFAULT_COMMANDS, "--seconds", str(DEFAULT_SECONDS)],
                                 capture_output=True, text=True, timeout=DEFAULT_SECONDS * 4 + 60)
            wall = time.perf_counter() - start
        finally:
            emulator.send_signal(signal.SIGINT)
            out, _ = emulator.communicate(timeout=30)
    report = json.loads(out.strip().splitlines()[-1])
    motion = report["powered_torso_motion"]
    return {"fell": run.returncode == 1, "exit": run.returncode, "dx_m": motion["dx_m"], "dy_m": motion["dy_m"],
            "yaw_rad": motion["yaw_rad"], "realtime_factor": report["realtime_factor"],
            "imu_reports": report["imu_reports"], "min_upright": report["powered_min_torso_upright"], "wall_s": wall,
            "last_line": run.stdout.strip().splitlines()[-1] if run.stdout.strip() else run.stderr.strip()[-200:]}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--policy", default="walk-zmp")
    parser.add_argument("--weights", default=None)
    args = parser.parse_args()
    os.environ.setdefault("PYTHONPATH", str(Path(__file__).resolve().parents[1] / "src"))
    print(f"{args.policy} ({args.weights or 'default weights'}), schedule {DEFAULT_COMMANDS!r}, {DEFAULT_SECONDS} s; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    sim = simulated(args.policy, args.weights)
    print(f"simulator: fell {sim['fell']}, dx {sim['dx_m']:.3f} m, dy {sim['dy_m']:.3f} m, "
          f"yaw {sim['yaw_rad']:.3f} rad ({sim['wall_s']:.1f} s wall)")
    hil = in_the_loop(args.policy, args.weights)
    print(f"HIL:       fell {hil['fell']} (exit {hil['exit']}), dx {hil['dx_m']:.3f} m, dy {hil['dy_m']:.3f} m, "
          f"yaw {hil['yaw_rad']:.3f} rad; real-time factor {hil['realtime_factor']:.2f}, "
          f"{hil['imu_reports']} IMU reports, min uprightness {hil['min_upright']:.3f}, {hil['wall_s']:.1f} s wall")
    print(f"hw run: {hil['last_line']}")


if __name__ == "__main__":
    main()
