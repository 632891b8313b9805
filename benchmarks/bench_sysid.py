"""Benchmark: wall time of a full 9-parameter fit over 16 synthetic runs of 6 s at 200 Hz (pendulum rig, XC330),
with at least 2,000 candidate evaluations, started from another motor model's catalogue values (2XL430).
Target: under 2 minutes on 2 cores.

Run: ``PYTHONPATH=src python benchmarks/bench_sysid.py [--evals 2048] [--popsize 32] [--start 2XL430]``
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.sysid.evaluate import evaluate
from toddlerbot.sysid.excitation import excitation_set
from toddlerbot.sysid.fit import fit
from toddlerbot.sysid.manifest import Manifest
from toddlerbot.sysid.rigs import PendulumRig
from toddlerbot.sysid.synthetic import synthesize


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--evals", type=int, default=2048)
    parser.add_argument("--popsize", type=int, default=32)
    parser.add_argument("--start", default="2XL430", help="catalogue motor whose values start the fit")
    args = parser.parse_args()
    motor = default_catalogue()["XC330"]
    truth, rig, noise = motor.actuator, PendulumRig(mass=0.49, length=0.1), np.radians(0.1)
    profiles = ("chirp", "steps", "lift_and_drop", "fast_steps")
    runs = synthesize(excitation_set(profiles, duration=6.0, rate=200.0), rig, truth, noise, seed=0)  # 4 x 4 kp
    manifest = Manifest(Path("bench.json"), motor, rig, tuple(runs))
    start = default_catalogue()[args.start].actuator
    t0, cpu0 = time.perf_counter(), time.process_time()
    result = fit(manifest, model="appendix", evals=args.evals, popsize=args.popsize, start=start, seed=1)
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    ev = evaluate(manifest, result.params)
    print(f"machine: {platform.machine()} {os.cpu_count()} cores, numpy {np.__version__}, "
          f"load average {os.getloadavg()[0]:.1f}")
    print(f"runs: {len(runs)} x {runs[0].duration:.0f} s at 200 Hz ({sum(len(r.time) for r in runs)} samples)")
    print(f"start: {args.start} catalogue values (MAE {evaluate(manifest, start).mae_deg:.2f} deg)")
    print(f"fit: {result.evals} evaluations in {result.generations} generations ({result.restarts} IPOP restarts, "
          f"first population {args.popsize}): {wall:.1f} s wall, {cpu:.1f} s CPU "
          f"({wall / result.evals * 1e3:.1f} ms per candidate)  target < 120 s: {'OK' if wall < 120 else 'MISSED'}")
    print(f"tracking: MAE {ev.mae_deg:.3f} deg, RMSE {ev.rmse_deg:.3f} deg (noise std {np.degrees(noise):.3f} deg)")
    for name in ("armature", "frictionloss", "tau_max", "kd_min", "tau_brake", "damping", "q_dot_tau_max",
                 "q_dot_max", "tau_q_dot_max"):
        got, want = getattr(result.params, name), getattr(truth, name)
        print(f"  {name:13s} {got:.4f} (truth {want:.4f}, {100 * (got / want - 1):+.1f} %)")


if __name__ == "__main__":
    main()
