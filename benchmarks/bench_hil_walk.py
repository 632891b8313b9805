"""A walking policy in hardware-in-the-loop against the simulator: the default tracking schedule (26 s, or its first
--seconds) walked by `hw run --imu emulator` through the driver, the safety layer and the emulated bus of `hw emulate
--hil` (the MuJoCo robot in real time, its IMU streamed as the BNO08x reports it), and by the same policy in the
simulator, on the flat floor or on a --terrain drawn from each of --terrain-seeds (HIL and simulator on the same
ground). Printed per run: falls, where the torso ended (dx, dy in the start heading's frame), its yaw change and the
tracking errors `eval tracking` computes, in HIL from the emulator's motion capture (`hw run --mocap emulator`), so
the two are measured alike; then the emulator's `powered_torso_motion` (from the moment torque came on, the ramp to
the pose included), its real-time factor and IMU reports, the control steps that came late (period over 1.5 x the
control period: the loop overran), wall time and load. Last, the HIL falls and the mean tracking errors of the walks
neither fell in, HIL against the simulator.

Run: PYTHONPATH=src python benchmarks/bench_hil_walk.py [--policy walk-zmp|walk-rl] [--weights FILE] [--runs N]
     [--seconds S] [--terrain rough:height=0.02 --terrain-seeds 0 1 2 3 4]
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
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.runner import run_policy
from toddlerbot.runtime.summary import RunSummary, summarize
from toddlerbot.runtime.tracking import DEFAULT_COMMANDS, DEFAULT_SECONDS
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.terrain import TerrainSpec, parse_terrain, terrain_model

LATE = 1.5
"""A control step whose period exceeds this many control periods came late (the loop overran)."""


def simulated(policy: str, weights: str | None, seconds: float, terrain: TerrainSpec | None, seed: int
              ) -> tuple[RunSummary, float]:
    """The policy's run in the simulator on ``terrain`` drawn from ``seed`` (None: the flat floor) and its wall
    time, s."""
    description = RobotDescription.load()
    robot = MuJoCoRobot(description, model=None if terrain is None else terrain_model(description, terrain, seed))
    start = time.perf_counter()
    result = run_policy(robot, make_policy(policy, robot, weights=weights), CommandSchedule.parse(DEFAULT_COMMANDS),
                        seconds, stop_on_fall=True)
    return summarize(result.log, result.fell, result.fall_time), time.perf_counter() - start


def in_the_loop(policy: str, weights: str | None, seconds: float, ground: list[str]) -> dict:
    """One `hw run` against `hw emulate --hil` on ``ground`` (its `--terrain` options), watched by the emulator's
    motion capture: its summary and late steps from the run's log, exit code and last line, and the emulator's
    statistics."""
    cli = [sys.executable, "-m", "toddlerbot.cli.main"]
    with tempfile.TemporaryDirectory() as tmp:
        cal, log = Path(tmp) / "emulated.yaml", Path(tmp) / "run.npz"
        emulator = subprocess.Popen([*cli, "hw", "emulate", "--hil", "--write-calibration", str(cal), *ground],
                                    stdout=subprocess.PIPE, text=True)
        try:
            port = emulator.stdout.readline().strip()
            start = time.perf_counter()
            run = subprocess.run([*cli, "hw", "run", "--port", port, "--calibration", str(cal), "--imu", "emulator",
                                  "--mocap", "emulator", "--log", str(log), "--policy", policy,
                                  *(["--weights", weights] if weights else []),
                                  "--command", DEFAULT_COMMANDS, "--seconds", str(seconds)],
                                 capture_output=True, text=True, timeout=seconds * 4 + 60)
            wall = time.perf_counter() - start
        finally:
            emulator.send_signal(signal.SIGINT)
            out, _ = emulator.communicate(timeout=30)
        run_log = RunLog.load(log) if log.is_file() else None
    report = json.loads(out.strip().splitlines()[-1])
    fell = run.returncode == 1
    return {"summary": None if run_log is None else summarize(run_log, fell, None), "exit": run.returncode,
            "fell": fell, "report": report, "wall_s": wall,
            "late": None if run_log is None else int(np.sum(run_log.step_period > LATE * run_log.control_dt)),
            "last_line": run.stdout.strip().splitlines()[-1] if run.stdout.strip() else run.stderr.strip()[-200:]}


def errors(summary: RunSummary) -> np.ndarray:
    t = summary.tracking
    return np.array([t.position_m, t.lin_vel_mps, t.ang_vel_radps])


def print_run(hil: dict) -> None:
    report, motion = hil["report"], hil["report"]["powered_torso_motion"]
    print(f"HIL:       exit {hil['exit']}, by motion capture: "
          f"{hil['summary'].motion_text() if hil['summary'] else 'no log'}")
    print(f"           emulator on {report['ground']} (powered, the ramp included): dx {motion['dx_m']:.3f} m, "
          f"dy {motion['dy_m']:.3f} m, yaw {motion['yaw_rad']:.3f} rad; real-time factor "
          f"{report['realtime_factor']:.2f}, {report['imu_reports']} IMU reports, min uprightness "
          f"{report['powered_min_torso_upright']:.3f}, {hil['late']} late control steps, {hil['wall_s']:.1f} s wall, "
          f"load {os.getloadavg()[0]:.1f}")
    print(f"hw run: {hil['last_line']}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--policy", default="walk-zmp")
    parser.add_argument("--weights", default=None)
    parser.add_argument("--runs", type=int, default=1, help="HIL runs per ground (each against a fresh emulator)")
    parser.add_argument("--seconds", type=float, default=DEFAULT_SECONDS, help="the schedule's first SECONDS")
    parser.add_argument("--terrain", default=None, help="NAME[:KEY=VALUE,...] (default: the flat floor)")
    parser.add_argument("--terrain-seeds", type=int, nargs="+", default=[0], help="one ground per seed")
    args = parser.parse_args()
    os.environ.setdefault("PYTHONPATH", str(Path(__file__).resolve().parents[1] / "src"))
    terrain = None if args.terrain is None else parse_terrain(args.terrain)
    seeds = args.terrain_seeds if terrain is not None else [0]
    print(f"{args.policy} ({args.weights or 'default weights'}), schedule {DEFAULT_COMMANDS!r}, "
          f"first {args.seconds} s, on {terrain or 'the flat floor'}{f' seeds {seeds}' if terrain else ''}; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    walks = []  # (simulator summary, HIL run) per walk
    for seed in seeds:
        ground = [] if terrain is None else ["--terrain", str(terrain), "--terrain-seed", str(seed)]
        sim, wall = simulated(args.policy, args.weights, args.seconds, terrain, seed)
        print(f"simulator{f' (seed {seed})' if terrain else ''}: "
              f"{f'fell at {sim.fall_time_s:.2f} s' if sim.fell else 'no fall'}, {sim.motion_text()} "
              f"({wall:.1f} s wall)")
        for _ in range(args.runs):
            hil = in_the_loop(args.policy, args.weights, args.seconds, ground)
            print_run(hil)
            walks.append((sim, hil))
    print(f"HIL falls {sum(hil['fell'] for _, hil in walks)} of {len(walks)}; simulator falls "
          f"{sum(sim.fell for sim, _ in walks)} of {len(walks)}")
    logged = [(sim, hil) for sim, hil in walks if hil["summary"] is not None]
    standing = [(sim, hil) for sim, hil in logged if not sim.fell and not hil["fell"]]
    compared, which = (standing, f"the {len(standing)} walks neither fell in") if standing else \
        (logged, f"all {len(logged)} walks, each up to its fall")
    if compared:
        sim_mean = np.mean([errors(sim) for sim, _ in compared], axis=0)
        hil_mean = np.mean([errors(hil["summary"]) for _, hil in compared], axis=0)
        print(f"mean tracking errors (position m / linear m/s / angular rad/s) of {which}: simulator "
              f"{' / '.join(f'{v:.3f}' for v in sim_mean)}, HIL {' / '.join(f'{v:.3f}' for v in hil_mean)}, "
              f"HIL / simulator {' / '.join(f'{v:.2f}' for v in hil_mean / sim_mean)}")


if __name__ == "__main__":
    main()
