"""Walking under each motor model (issue 44, item 2): the sim-to-sim spread a user should expect before a real robot.

The shipped walk-rl and walk-zmp walk the robot built under each motor-model condition of
`toddlerbot.sim.motor_conditions` (appendix, extended and DC-motor models with the catalogue's parameters for the
robot's motors, the terms the catalogue lacks from the XL330-M288 fits in ``--fits``; each moved weaker and
stronger by ``--standard-errors`` of that fit's relative standard errors; the extended and DC-motor models with the
fit's load friction too). Per condition and policy: Table 7's tracking errors over the default schedule
(`toddlerbot.runtime.tracking`, 26 s) and the falls over the ten reach commands (`runtime.robustness`) on the
nominal robot and under ``--kick`` m/s kicks on ``--seeds`` seeds. Trials run in ``--workers`` subprocesses that
print one JSON line each. The defaults are the grid of docs/sysid.md ("Walking under each motor model": 12 minutes
on the shared 2-core VM).

Run: PYTHONPATH=src python benchmarks/bench_motor_models.py [--conditions "appendix,dc_motor weaker"] [--seeds 1]
     [--seconds 6] [--kick 0.2] [--standard-errors 1] [--workers 2] [--fits benchmarks/results/xl330_fits]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

from json_workers import worker_rows
from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.robustness import Condition, conditions, reach_commands, run_trial
from toddlerbot.runtime.tracking import evaluate_policy
from toddlerbot.sim.motor_conditions import motor_conditions, reference_fits
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

POLICIES = ("walk-rl", "walk-zmp")
FITS = Path(__file__).parent / "results" / "xl330_fits"
WIDTH, CELL = 28, 11
"""Characters of the table's first column and of every other cell."""


def _descriptions(args) -> dict[str, RobotDescription]:
    return motor_conditions(RobotDescription.load(), reference_fits(args.fits), args.standard_errors)


def _trial_conditions(args) -> list[tuple[Condition, list[int]]]:
    """The nominal robot on one seed (no seed changes it) and the kicks on ``--seeds``."""
    by_name = {c.name: c for c in conditions(kicks=(args.kick,))}
    return [(by_name["nominal"], [0]), (by_name[f"kicks {args.kick:g} m/s"], list(range(args.seeds)))]


def _jobs(args, names: list[str]) -> list[tuple]:
    """("track", condition, policy) and ("walk", condition, policy, command, trial condition, seed) of every run."""
    reach = {p: make_policy(p, MuJoCoRobot(RobotDescription.load())).command_reach for p in POLICIES}
    jobs = [("track", name, policy) for name in names for policy in POLICIES]
    jobs += [("walk", name, policy, command, trial.name, seed) for name in names for policy in POLICIES
             for trial, seeds in _trial_conditions(args) for command in reach_commands(reach[policy]) for seed in seeds]
    return jobs


def worker(args, names: list[str]) -> None:
    """Run every `--workers`-th job starting at `--worker`, one JSON line each."""
    descriptions = _descriptions(args)
    trials = {c.name: c for c, _ in _trial_conditions(args)}
    for i, job in enumerate(_jobs(args, names)):
        if i % args.workers != args.worker:
            continue
        kind, name, policy = job[:3]
        if kind == "track":
            result = evaluate_policy(descriptions[name], policy)
            row = {**result.summary(), "fell": bool(result.falls)}
        else:
            command, trial, seed = job[3:]
            fall = run_trial(descriptions[name], lambda robot, p=policy: make_policy(p, robot), command,
                             trials[trial], seed, args.seconds).fall_time
            row = {"trial": trial, "fell": fall is not None}
        print(json.dumps({"kind": kind, "condition": name, "policy": policy, **row}), flush=True)


def print_table(args, names: list[str], rows: list[dict], wall: float) -> None:
    trials = [c.name for c, _ in _trial_conditions(args)]
    print(f"falls / trials over the reach ({args.seconds:g} s each; kicks on {args.seeds} seed(s)) and Table 7 "
          f"tracking errors (26 s schedule; * fell, errors until the fall), motor parameters moved by "
          f"{args.standard_errors:g} standard error(s) ({platform.processor() or platform.machine()}, {wall:.0f} s "
          f"wall, {args.workers} workers)")
    columns = [trial.removesuffix(" m/s") for trial in trials] + ["pos m", "lin m/s", "ang rad/s"]
    print("condition".ljust(WIDTH) + "".join(policy.rjust(len(columns) * CELL) for policy in POLICIES))
    print("".ljust(WIDTH) + "".join(column.rjust(CELL) for column in columns) * len(POLICIES))
    for name in names:
        cells = []
        for policy in POLICIES:
            mine = [r for r in rows if r["condition"] == name and r["policy"] == policy]
            for trial in trials:
                walks = [r for r in mine if r["kind"] == "walk" and r["trial"] == trial]
                cells.append(f"{sum(r['fell'] for r in walks)}/{len(walks)}")
            track = next(r for r in mine if r["kind"] == "track")
            mark = "*" if track["fell"] else ""
            cells += [f"{track[key]:.3f}{mark}" for key in ("position_m", "lin_vel_mps", "ang_vel_radps")]
        print(name.ljust(WIDTH) + "".join(cell.rjust(CELL) for cell in cells))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--conditions", default=None, help="comma-separated motor-model conditions (default: all)")
    parser.add_argument("--fits", type=Path, default=FITS, help="folder of the reference fits <model>.json")
    parser.add_argument("--standard-errors", type=float, default=1.0, help="how far the weaker/stronger moves go")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--kick", type=float, default=0.2, help="kick speed, m/s")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    known = list(_descriptions(args))
    names = args.conditions.split(",") if args.conditions else known
    if set(names) - set(known):
        parser.error(f"unknown condition(s) {sorted(set(names) - set(known))}; expected some of {known}")
    if args.worker is not None:
        worker(args, names)
        return
    start = time.perf_counter()
    rows = worker_rows(__file__, args.workers)
    print_table(args, names, rows, time.perf_counter() - start)


if __name__ == "__main__":
    main()
