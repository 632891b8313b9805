"""Success over seeds and timings of the wagon skill chain in simulation (`toddlerbot chain run wagon`): per seed
the outcome, the wagon's displacement, the grasp -> next switch time and the wall time of one run (no video).

Run: PYTHONPATH=src python benchmarks/bench_chain.py [--seeds 10]
"""

from __future__ import annotations

import argparse
import platform

import numpy as np

from toddlerbot.manipulation.chaining.sim_run import run_in_sim
from toddlerbot.manipulation.chaining.spec import load_chain
from toddlerbot.robot.description import RobotDescription


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args()
    description = RobotDescription.load(variant="gripper")
    chain = load_chain("wagon", tuple(description.groups))
    results = [run_in_sim(chain, seed, description=description) for seed in range(args.seeds)]
    for r in results:
        print(f"seed {r.seed}: {'success' if r.success else 'FAILED ' + str(r.failure or r.checks)}, wagon moved "
              f"{r.displacement_m['wagon']:.3f} m, switch at {r.switch_time_s:.2f} s, {r.sim_seconds:.1f} s "
              f"simulated in {r.wall_seconds:.1f} s")
    moved = np.array([r.displacement_m["wagon"] for r in results])
    wall = np.array([r.wall_seconds for r in results])
    print(f"{platform.machine()}, {platform.python_version()}: success {sum(r.success for r in results)}/"
          f"{len(results)}; displacement {moved.min():.3f}-{moved.max():.3f} m (mean {moved.mean():.3f}); "
          f"wall {wall.min():.1f}-{wall.max():.1f} s per run (mean {wall.mean():.1f})")


if __name__ == "__main__":
    main()
