"""Getting up after a fall: the `get-up` policy on robots knocked over while walking (`policies.get_up_trials`).

Each seed walks the nominal robot with walk-rl at a seeded command within its reach, kicks it once (1-2 m/s,
seeded) towards its back or its front (or a side: `--sides left right`), lets it settle 1.5 s with the targets
held, then hands it to the get-up policy for 10 s. Success: the torso at >= 90 % of its standing height with
uprightness >= 0.9 for 0.5 s (the simulator's ground truth judges; the policy reads only the IMU). Printed per side:
successes out of the seeds that fell, time to stand (median, max), how many then walked 5 s with walk-rl without a
fall, attempts used, the longest time any motor stayed above its stall torque, the control steps with the fall
guard's lowered gains, how the robots lay, and the machine.

Run: PYTHONPATH=src python benchmarks/bench_get_up.py [--seeds 20] [--first-seed 0] [--sides front left]
     [--tracker get_up_front=POLICY.npz | --open-loop]  (default: the shipped trackers, if any)
"""

from __future__ import annotations

import argparse
import collections
import os
import platform
import time

import numpy as np

from toddlerbot.policies.get_up_trials import KICK_DIRECTION, WALK_ON_S, fallen_robot, get_up_trial
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import SimulationError


def cpu_model() -> str:
    """The CPU's model name (Linux), else what `platform` says."""
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def side_figures(description: RobotDescription, side: str, seeds: range,
                 trackers: dict[str, str] | None = None) -> str:
    trials, diverged, skipped = [], [], collections.Counter()
    for seed in seeds:
        try:
            fallen = fallen_robot(description, seed, side)
        except SimulationError:
            skipped["the simulation diverged during the fall"] += 1
            continue
        if fallen is None:
            skipped["the kick did not knock it over"] += 1
            continue
        try:
            trials.append(get_up_trial(fallen, trackers))
        except SimulationError:
            diverged.append(seed)
    stood = [t for t in trials if t.stood]
    times = np.array([t.time_to_stand for t in stood])
    timing = f"time to stand median {np.median(times):.2f} s, max {times.max():.2f} s" if stood else "none stood"
    attempts = collections.Counter(t.attempts for t in trials)
    lying = collections.Counter(t.lying[0] if t.lying else "upright" for t in trials)
    failed = ", ".join([str(t.seed) for t in trials if not t.stood] + [f"{s} (diverged)" for s in diverged]) or "none"
    lines = [f"{side}: {len(stood)}/{len(trials) + len(diverged)} stood within 10 s "
             f"(seeds {seeds.start}-{seeds.stop - 1}; failed: {failed}); {timing}",
             f"  then walked {WALK_ON_S:g} s with walk-rl without a fall: "
             f"{sum(bool(t.walked_on) for t in stood)} of {len(stood)}",
             f"  attempts used: {dict(sorted(attempts.items()))}; first lying: {dict(lying)}",
             f"  longest time a motor stayed above its stall torque: "
             f"{max((t.longest_over_stall for t in trials), default=0.0):.2f} s; steps with lowered fall-guard "
             f"gains: {sum(t.lowered_gain_steps for t in trials)}"]
    lines += [f"  {n} seed(s) gave no fallen state: {why}" for why, n in skipped.items()]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--sides", nargs="+", choices=tuple(KICK_DIRECTION), default=("back", "front"),
                        help="the sides kicked towards (left and right: sideways kicks)")
    parser.add_argument("--tracker", action="append", default=[], metavar="MOTION=POLICY",
                        help="play MOTION with this exported tracking policy (repeatable)")
    parser.add_argument("--open-loop", action="store_true", help="play every motion open-loop (no shipped tracker)")
    args = parser.parse_args()
    description = RobotDescription.load()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    trackers = dict(item.split("=", 1) for item in args.tracker) if args.tracker or args.open_loop else None
    played = "open-loop" if trackers == {} else f"trackers {trackers}" if trackers else "the shipped trackers"
    print(f"machine: {cpu_model()}, {os.cpu_count()} cores; {args.seeds} seeds per side; {played}")
    for side in args.sides:
        started = time.perf_counter()
        print(side_figures(description, side, seeds, trackers))
        print(f"  ({time.perf_counter() - started:.0f} s of wall time)")


if __name__ == "__main__":
    main()
