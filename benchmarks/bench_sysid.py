"""Benchmark: wall time of a full 9-parameter fit over 16 synthetic runs of 6 s at 200 Hz (pendulum rig, XC330),
with at least 2,000 candidate evaluations. Target: under 2 minutes on 2 cores.

Run: ``PYTHONPATH=src python benchmarks/bench_sysid.py [--evals 2048] [--popsize 32]``
"""

from __future__ import annotations

import argparse
import dataclasses
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
    args = parser.parse_args()
    motor = default_catalogue()["XC330"]
    truth, rig, noise = motor.actuator, PendulumRig(mass=0.49, length=0.1), np.radians(0.1)
    runs = synthesize(excitation_set(duration=6.0, rate=200.0), rig, truth, noise, seed=0)  # 4 profiles x 4 kp
    manifest = Manifest(Path("bench.json"), motor, rig, tuple(runs))
    fields = dataclasses.asdict(truth)
    start = truth.replace(**{k: v * (1.3 if i % 2 else 0.75) for i, (k, v) in enumerate(fields.items())
                             if k != "kp_scale"})
    t0 = time.perf_counter()
    result = fit(manifest, evals=args.evals, popsize=args.popsize, start=start, seed=1)
    wall = time.perf_counter() - t0
    ev = evaluate(manifest, result.params)
    print(f"machine: {platform.machine()} {os.cpu_count()} cores, numpy {np.__version__}")
    print(f"runs: {len(runs)} x {runs[0].duration:.0f} s at 200 Hz ({sum(len(r.time) for r in runs)} samples)")
    print(f"fit: {result.evals} evaluations in {result.generations} generations of {args.popsize}: {wall:.1f} s "
          f"({wall / result.evals * 1e3:.1f} ms per candidate)  target < 120 s: {'OK' if wall < 120 else 'MISSED'}")
    print(f"tracking: MAE {ev.mae_deg:.3f} deg, RMSE {ev.rmse_deg:.3f} deg (noise std {np.degrees(noise):.3f} deg)")
    for name in ("armature", "frictionloss", "tau_max", "kd_min", "tau_brake", "damping"):
        got, want = getattr(result.params, name), getattr(truth, name)
        print(f"  {name:13s} {got:.4f} (truth {want:.4f}, {100 * (got / want - 1):+.1f} %)")


if __name__ == "__main__":
    main()
