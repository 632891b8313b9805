"""Falls of a walking policy per command x perturbation (`toddlerbot.runtime.robustness`).

Ten commands across the policy's reach, each walked for `--seconds` under every condition (nominal, torso 10 %
heavier, floor friction 0.5, small random perturbations, velocity kicks of 0.1, 0.2 and 0.3 m/s, the upper body
held at a random pose 0.3 and 0.5 of the way to its limits: with `--variant` only, unless named in `--conditions`)
and `--seeds` seeds, on the robot of `--variant` with the fitted motor parameters of `--motor-params` (sysID
params.json files, as `sim run` takes them; `benchmarks/bench_motor_models.py` walks both policies under each motor
model);
prints a table of falls (falls / trials per cell) and the totals per condition. Trials run in `--workers`
subprocesses that print one JSON line per trial (nothing is pickled between processes).

`--terrain NAME[:KEY=VALUE,...]` (repeatable; `toddlerbot.sim.terrain`, e.g. `rough:height=0.02`,
`slope:degrees=-10`) adds a terrain axis: every condition is walked on each terrain, drawn from the trial's seed, and
a column is a (condition, terrain) pair. With `--terrain` the conditions default to `nominal` alone.

`--stops`: every trial stops on the way (`runtime.robustness.stop_schedule`: a zero command for 3 s from 2.4-2.9 s,
then the command again), so under kicks it is kicked walking, standing and walking again (walk-rl stands still at a
zero command: `policies.stand_still`).

`--kick-grid SPEED` instead kicks once per trial, in 8 directions around the heading x 6 moments of one gait
cycle (`runtime.robustness.kick_grid`), standing and walking half the forward reach, and prints which fall.

Run: PYTHONPATH=src python benchmarks/bench_walk_robustness.py [--policy walk-zmp|walk-rl] [--weights F.npz]
     [--variant gripper] [--motor-params P.json] [--seeds 3] [--seconds 8] [--workers 2]
     [--conditions nominal,perturbed,"posed 0.3"] [--kick-grid 0.3]
     [--terrain rough:height=0.02 --terrain slope:degrees=10]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

from json_workers import worker_rows
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies import check_policy_options, make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.robustness import conditions, directed_kick_trial, kick_grid, reach_commands, run_trial
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.terrain import parse_terrain


def _description(args) -> RobotDescription:
    return RobotDescription.load(variant=args.variant, motor_params=args.motor_params)


def _policy_factory(args):
    return lambda robot: make_policy(args.policy, robot, weights=args.weights, symmetric=not args.asymmetric,
                                     stand=not args.step_in_place)


def _reach(args, description):
    return make_policy(args.policy, MuJoCoRobot(description), weights=args.weights).command_reach


def _label(args) -> str:
    return args.policy + (f" ({args.weights})" if args.weights else "") + (" asymmetric" if args.asymmetric else "") \
        + (" stepping in place" if args.step_in_place else "") \
        + "".join(f" with {path}" for path in args.motor_params)


def _columns(args, names):
    """(condition, terrain text or None) of every column of the table."""
    return [(name, terrain) for name in names for terrain in (args.terrain or [None])]


def _column_label(name, terrain) -> str:
    return name if terrain is None else f"{name} {terrain}"


def _jobs(args, names, description):
    """(command, condition, seed, terrain) of every trial; the commands span the policy's reach."""
    reach = _reach(args, description)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    return [(c, name, seed, terrain) for name, terrain in _columns(args, names) for c in reach_commands(reach)
            for seed in seeds]


def _grid_jobs(args, description):
    """(command, row, column, direction, kick time) of every `--kick-grid` trial."""
    commands = [(0.0, 0.0, 0.0), (_reach(args, description).high[0] / 2, 0.0, 0.0)]
    return [(c, *cell) for c in commands for cell in kick_grid()]


def grid_worker(args) -> None:
    """Run every `--workers`-th `--kick-grid` trial starting at `--worker`, one JSON line each."""
    description = _description(args)
    for k, (command, i, j, direction, kick_time) in enumerate(_grid_jobs(args, description)):
        if k % args.workers == args.worker:
            fall = directed_kick_trial(description, _policy_factory(args), command, args.kick_grid, direction,
                                       kick_time)
            print(json.dumps({"command": command, "cell": [i, j], "fall_time": fall}), flush=True)


def print_grid(args, rows, wall) -> None:
    directions = sorted({r["cell"][0] for r in rows})
    print(f"{_label(args)}: falls after one {args.kick_grid:g} m/s kick, by direction (deg from the heading, "
          f"counter-clockwise: 90 = to the left) x moment in the gait cycle "
          f"({platform.processor() or platform.machine()}, {wall:.0f} s wall)")
    for command in dict.fromkeys(tuple(r["command"]) for r in rows):
        print(f"command ({command[0]:+.3f}, {command[1]:+.3f}, {command[2]:+.2f})")
        for i in directions:
            cells = sorted((r for r in rows if tuple(r["command"]) == command and r["cell"][0] == i),
                           key=lambda r: r["cell"][1])
            marks = " ".join("X" if r["fall_time"] is not None else "." for r in cells)
            print(f"  {360 * i / len(directions):5.0f}  {marks}  {sum(r['fall_time'] is not None for r in cells)}")
        print(f"  all    {sum(r['fall_time'] is not None for r in rows if tuple(r['command']) == command)}"
              f"/{sum(tuple(r['command']) == command for r in rows)}")


def worker(args, names) -> None:
    """Run every `--workers`-th trial starting at `--worker` and print each as a JSON line."""
    description = _description(args)
    by_name = {c.name: c for c in conditions()}
    for i, (command, name, seed, terrain) in enumerate(_jobs(args, names, description)):
        if i % args.workers != args.worker:
            continue
        trial = run_trial(description, _policy_factory(args), command, by_name[name], seed, args.seconds,
                          None if terrain is None else parse_terrain(terrain), args.stops)
        print(json.dumps({"command": trial.command, "condition": name, "seed": seed, "terrain": terrain,
                          "fall_time": trial.fall_time}), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--policy", default="walk-zmp")
    parser.add_argument("--weights", default=None)
    parser.add_argument("--variant", default=None, help="spec variant (e.g. gripper)")
    parser.add_argument("--motor-params", action="append", default=[], metavar="P.json",
                        help="fitted actuator parameters (sysid params.json; repeatable), as sim run takes them")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--conditions", default=None,
                        help="comma-separated (default: all; the posed ones only with --variant, as a policy of the "
                             "base robot is not trained to walk with its arms posed)")
    parser.add_argument("--kick-grid", type=float, default=None, metavar="SPEED",
                        help="one kick of SPEED m/s per trial over directions x gait phases instead")
    parser.add_argument("--asymmetric", action="store_true",
                        help="walk-rl without its mirror image (docs/rl.md \"Mirror symmetry\")")
    parser.add_argument("--step-in-place", action="store_true",
                        help="walk-rl stepping in place at a zero command instead of standing still (docs/rl.md)")
    parser.add_argument("--terrain", action="append", default=None, metavar="NAME[:KEY=VALUE,...]",
                        help="walk every condition on this terrain too (repeatable), drawn from the trial's seed")
    parser.add_argument("--stops", action="store_true",
                        help="every trial stands at a zero command for 3 s on the way (stop_schedule)")
    parser.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    try:
        check_policy_options(args.policy, weights=args.weights)  # walk-zmp would ignore --weights
        for text in args.terrain or []:
            parse_terrain(text)
        _description(args)
    except ToddlerbotError as exc:
        parser.error(str(exc))
    names = args.conditions.split(",") if args.conditions else ["nominal"] if args.terrain else \
        [c.name for c in conditions() if args.variant or not c.upper_body_pose]
    unknown = set(names) - {c.name for c in conditions()}
    if unknown:
        parser.error(f"unknown condition(s) {sorted(unknown)}; expected some of {[c.name for c in conditions()]}")
    if args.worker is not None:
        grid_worker(args) if args.kick_grid is not None else worker(args, names)
        return
    start = time.perf_counter()
    rows = worker_rows(__file__, args.workers)
    wall = time.perf_counter() - start
    if args.kick_grid is not None:
        print_grid(args, rows, wall)
        return
    description = _description(args)
    commands = list(dict.fromkeys(tuple(c) for c, _, _, _ in _jobs(args, names, description)))
    columns = _columns(args, names)
    robot = f"{_label(args)} ({description.spec.variant or 'base robot'})"
    stops = ", stopping 3 s from 2.4-2.9 s" if args.stops else ""
    print(f"{robot}: falls / trials, {args.seeds} seed(s) x {args.seconds:g} s per cell{stops} "
          f"({platform.processor() or platform.machine()}, {wall:.0f} s wall, {args.workers} workers)")
    width = max(len(_column_label(*c)) for c in columns) + 2
    print("command (vx, vy, yaw)".ljust(24) + "".join(_column_label(*c).rjust(width) for c in columns))
    in_column = lambda r, c: (r["condition"], r.get("terrain")) == c  # noqa: E731
    for command in commands:
        cells = []
        for column in columns:
            trials = [r for r in rows if tuple(r["command"]) == command and in_column(r, column)]
            cells.append(f"{sum(r['fall_time'] is not None for r in trials)}/{len(trials)}".rjust(width))
        print(f"({command[0]:+.3f}, {command[1]:+.3f}, {command[2]:+.2f})".ljust(24) + "".join(cells))
    totals = []
    for column in columns:
        trials = [r for r in rows if in_column(r, column)]
        totals.append(f"{sum(r['fall_time'] is not None for r in trials)}/{len(trials)}".rjust(width))
    print("all".ljust(24) + "".join(totals))


if __name__ == "__main__":
    main()
