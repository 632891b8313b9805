"""walk-rl at a zero command: the torso's drift over `--seconds` on robots perturbed from each seed
(`Perturbation.sample`: joint offsets, torso mass, friction, motor parameters), standing still
(`policies.stand_still`, the default) and stepping in place (`--step-in-place`); per seed, max and mean.
`--plot` draws the torso's paths. issue 42's bar: at most 0.03 m in 60 s.

Run: PYTHONPATH=src python benchmarks/bench_stand_still.py [--seeds 6] [--seconds 60] [--plot paths.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench_get_up import cpu_model
from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.runner import run_policy
from toddlerbot.sim.perturbation import Perturbation, perturbed_robot


def torso_path(description: RobotDescription, seed: int, seconds: float, stand: bool) -> tuple[np.ndarray, bool]:
    """(torso (x, y) per control step relative to the start, m; whether it fell) of walk-rl at a zero command."""
    robot = perturbed_robot(description, Perturbation.sample(seed, description))
    result = run_policy(robot, make_policy("walk-rl", robot, stand=stand), lambda t: np.zeros(3), seconds)
    xy = np.asarray(result.log.base_pos)[:, :2]
    return xy - xy[0], result.fall_time is not None


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--plot", default=None, help="write the torso paths to this image")
    args = parser.parse_args()
    description = RobotDescription.load()
    start = time.perf_counter()
    paths = {}
    for stand, label in ((True, "standing still"), (False, "stepping in place")):
        runs = [torso_path(description, seed, args.seconds, stand) for seed in range(args.seeds)]
        paths[label] = [xy for xy, _ in runs]
        drift = [float(np.linalg.norm(xy[-1])) for xy, _ in runs]
        falls = sum(fell for _, fell in runs)
        print(f"{label}: drift in {args.seconds:g} s per seed " + " ".join(f"{d:.3f}" for d in drift)
              + f" m; max {max(drift):.3f}, mean {np.mean(drift):.3f} m; falls {falls}/{args.seeds}")
    print(f"({cpu_model()}, {time.perf_counter() - start:.0f} s wall)")
    if args.plot:
        plot_paths(paths, args.seconds, args.plot)


def plot_paths(paths: dict[str, list[np.ndarray]], seconds: float, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from toddlerbot.files import save_figure

    fig, axes = plt.subplots(1, len(paths), figsize=(5 * len(paths), 4.6), sharex=True, sharey=True)
    for ax, (label, runs) in zip(axes, paths.items()):
        for seed, xy in enumerate(runs):
            ax.plot(100 * xy[:, 0], 100 * xy[:, 1], lw=0.8, label=f"seed {seed}")
            ax.plot(100 * xy[-1, 0], 100 * xy[-1, 1], "k.", ms=4)
        ax.add_patch(plt.Circle((0, 0), 3.0, fill=False, ls="--", color="gray"))
        ax.set_title(f"walk-rl {label}, {seconds:g} s at a zero command")
        ax.set_xlabel("torso x, cm")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("torso y, cm")
    axes[-1].legend(fontsize=7, loc="lower right")
    save_figure(fig, out)


if __name__ == "__main__":
    main()
