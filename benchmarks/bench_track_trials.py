"""A motion played by open-loop `replay` against an exported tracking policy (`track`), on perturbed robots in the CPU
simulator (`toddlerbot.rl.track_trials`): completion rate and tracking error per condition.

Conditions: nominal, torso +10 %, floor friction 0.5, torso mass / friction / every motor parameter drawn within
+-10 % from the seed, and one 0.2 m/s kick at a seeded time and direction. A trial completed when the robot never
left the motion's reference by the tracking environment's termination thresholds and ends standing.

Run: PYTHONPATH=src python benchmarks/bench_track_trials.py --motion get_up_front --weights POLICY.npz [--seeds 20]
     [--first-seed 1000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from bench_get_up import cpu_model
from toddlerbot.rl.track_trials import CONDITIONS, MotionTrials
from toddlerbot.robot.description import RobotDescription


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--motion", required=True, help="built-in motion name or motion file")
    parser.add_argument("--weights", required=True, help="exported tracking policy (.npz or .onnx)")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=1000)
    args = parser.parse_args()
    started = time.perf_counter()
    trials = MotionTrials(RobotDescription.load(), args.motion)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    print(f"machine: {cpu_model()}, {os.cpu_count()} cores; motion {args.motion}; policy {args.weights}; "
          f"seeds {seeds.start}-{seeds.stop - 1}")
    print("| condition | player | completed | stood | motor RMSE, rad (median) | tilt error, rad (median) | "
          "final heading error, rad (median of abs) |")
    print("|---|---|---|---|---|---|---|")
    for condition in CONDITIONS:
        for player in ("replay", "track"):
            runs = [trials.trial(player, condition, seed, args.weights) for seed in seeds]
            completed = sum(r.completed for r in runs)
            stood = sum(r.stood for r in runs)
            print(f"| {condition.name} | {player} | {completed}/{len(runs)} | {stood}/{len(runs)} | "
                  f"{np.median([r.motor_rmse for r in runs]):.3f} | "
                  f"{np.median([r.tilt_error for r in runs]):.3f} | "
                  f"{np.median([abs(r.heading_error) for r in runs]):.3f} |", flush=True)
    print(f"({time.perf_counter() - started:.0f} s of wall time)")


if __name__ == "__main__":
    main()
