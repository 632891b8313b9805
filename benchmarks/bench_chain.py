"""Success rate over seeds and timings of the wagon skill chain in simulation (`toddlerbot chain run wagon`): per
seed the outcome (success: the wagon moved at least 0.5 m, both hands on the handle and the robot upright at the
end), the wagon's displacement, the grasp -> next switch time, the grasp retries and re-grasps (the push's
recoveries) with their times, each hand's grip through the push (the weaker finger pad's least normal force, how far
the handle slid along the fingers, how near the grasp point came to the handle's end) and the wall time of one run
(no video); then the success rate and the retries and re-grasps in all. `--pose-offset` and
`--wagon-shift` perturb the start to show the margin; `--variation wide` draws each seed's scene from the wagon
task's wide ranges (handle height, arm start pose, light; docs/manipulation.md).

Run: PYTHONPATH=src python benchmarks/bench_chain.py [--seeds 20] [--first-seed 0] [--pose-offset 0.01]
                                                    [--wagon-shift 0.01,0] [--variation wide]
                                                    [--scripted-grasp] [--chain FILE]
The grasp is the chain's: the shipped wagon diffusion policy (`dp/checkpoints/wagon.pt`, torch: the [dp] extra; its
sampling noise seeded by the run's seed), or with `--scripted-grasp` the script. `--chain FILE` runs a chain file in
place of the shipped wagon chain (e.g. a copy whose grasp names another checkpoint: `checkpoint: run/checkpoint.pt`).
"""

from __future__ import annotations

import argparse
import platform

import numpy as np

from toddlerbot.robot.description import RobotDescription
from toddlerbot.skills.sim_run import SimChainResult, run_in_sim
from toddlerbot.skills.spec import load_chain
from toddlerbot.tasks.base import StartPerturbation


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--pose-offset", type=float, default=0.0, help="rad, each motor's start off home, at most")
    parser.add_argument("--wagon-shift", default="0,0", help="x,y m, added to the seed's wagon shift")
    parser.add_argument("--scripted-grasp", action="store_true", help="grasp by script, not with the chain's policy")
    parser.add_argument("--variation", default="default", help="the wagon scene's variation the seeds draw from")
    parser.add_argument("--chain", default="wagon", help="a chain file of the wagon scene (default: the shipped one)")
    args = parser.parse_args()
    shift = tuple(float(v) for v in args.wagon_shift.split(","))
    perturbation = StartPerturbation(args.pose_offset, (shift[0], shift[1]))
    description = RobotDescription.load(variant="gripper")
    chain = load_chain(args.chain, tuple(description.groups))
    if args.scripted_grasp:
        chain = chain.with_scripted_grasps()
    print(f"{chain.name} chain ({args.chain}), {perturbation}, scene variation {args.variation}")
    print("seed  outcome                  moved m  switch s  grip N (L/R)   slide mm (L/R)  to end mm (L/R)  wall s  "
          "retries, re-grasps (s)")
    results = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        results.append(run_in_sim(chain, seed, description=description, perturbation=perturbation,
                                  variation=args.variation))
        print(_row(results[-1]), flush=True)
    moved = np.array([r.displacement_m["wagon"] for r in results])
    forces = np.array([g.min_force_n for r in results for g in r.grip.values()])
    slides = np.array([g.slide_m for r in results for g in r.grip.values()])
    to_end = np.array([g.to_end_m for r in results for g in r.grip.values()])
    wall = np.array([r.wall_seconds for r in results])
    print(f"{platform.machine()}, {platform.python_version()}: success {sum(r.success for r in results)}/"
          f"{len(results)}; displacement {moved.min():.3f}-{moved.max():.3f} m (mean {moved.mean():.3f}); weakest "
          f"pad force {forces.min():.1f} N (median {np.median(forces):.1f}); handle slide at most "
          f"{1e3 * slides.max():.1f} mm; grasp point at least {1e3 * to_end.min():.0f} mm from the handle's end; "
          f"wall {wall.min():.1f}-{wall.max():.1f} s per run (mean {wall.mean():.1f}); grasp by "
          f"{', '.join(sorted({r.driven_by['grasp'] for r in results}))}; {_count(results, 'retry')} grasp retries "
          f"and {_count(results, 'recover')} re-grasps in all, on {sum(bool(r.recoveries) for r in results)} seeds")


def _count(results: list[SimChainResult], kind: str) -> int:
    return sum(r.kind == kind for result in results for r in result.recoveries)


def _row(r: SimChainResult) -> str:
    outcome = "success" if r.success else "FAILED " + (r.failure or ",".join(k for k, v in r.checks.items() if not v))
    grip = r.grip.values()
    return (f"{r.seed:4d}  {outcome[:23]:23s}  {r.displacement_m['wagon']:7.3f}  {r.switch_time_s or np.nan:8.2f}  "
            f"{'/'.join(f'{g.min_force_n:.1f}' for g in grip):13s}  "
            f"{'/'.join(f'{1e3 * g.slide_m:.1f}' for g in grip):14s}  "
            f"{'/'.join(f'{1e3 * g.to_end_m:.0f}' for g in grip):15s}  {r.wall_seconds:6.1f}  "
            + (", ".join(f"{'retry' if x.kind == 'retry' else 're-grasp'} {x.time_s:.2f}" for x in r.recoveries)
               or "-"))


if __name__ == "__main__":
    main()
