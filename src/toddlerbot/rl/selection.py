"""Checkpoint selection (`rl export RUN --select K`): a run's last K checkpoints, each exported and walked by its
runtime policy in the simulator over one fixed set of trials on seeds that no benchmark uses, ranked by falls and
then by how far the straight walks strayed from their commands; the best is the one exported, the table in its
metadata. So a documented recipe ends in the file that is shipped, with no checkpoint picked by hand on the
benchmark's own seeds.

The trials: every command of the policy's reach (`runtime.robustness.reach_commands`) on each seed, under
``kick`` m/s kicks on the flat floor and, for each of ``terrains``, on that ground (drawn from the seed) without
kicks."""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.robustness import Condition, conditions, reach_commands, run_trial
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.terrain import parse_terrain

SELECTION_SEEDS = (1000, 1001)
"""Seeds of the selection trials: disjoint from `bench_walk_robustness.py`'s (0-5 by default) and from the terrain
figures' (docs/rl.md "Walking on terrain")."""


@dataclass(frozen=True)
class SelectionTrials:
    """What every candidate checkpoint walks."""

    kick: float = 0.3
    """m/s kicks on the flat floor (0: none)."""
    terrains: tuple[str, ...] = ()
    """Grounds walked without kicks (`toddlerbot.sim.terrain` texts)."""
    seeds: tuple[int, ...] = SELECTION_SEEDS
    seconds: float = 8.0

    def __post_init__(self) -> None:
        for text in self.terrains:
            parse_terrain(text, "--select-terrain")  # one line for a bad one, before anything is walked

    def columns(self) -> list[tuple[Condition, str | None]]:
        """(condition, terrain) of each column: the benchmark's kick condition on the flat floor, then its nominal
        condition on each terrain."""
        nominal, *_, kicked = conditions(kicks=(self.kick,), poses=())  # nominal first, the kick last
        return [(kicked, None), *((nominal, text) for text in self.terrains)]


def checkpoint_score(policy_file: Path, policy_name: str, description: RobotDescription,
                     trials: SelectionTrials) -> dict:
    """Falls and trials of ``policy_file`` played by ``policy_name`` over ``trials``, and the mean distance (m)
    between where the straight walks (no turn commanded) ended and where their command would have taken them."""
    factory = lambda robot: make_policy(policy_name, robot, weights=policy_file)  # noqa: E731
    reach = getattr(factory(MuJoCoRobot(description)), "command_reach", None)
    if reach is None:
        raise ToddlerbotError(f"--select: {policy_name} does not walk velocity commands; selection walks a walking "
                              "policy's reach")
    falls, count, strays = 0, 0, []
    for condition, terrain in trials.columns():
        ground = None if terrain is None else parse_terrain(terrain)
        for command in reach_commands(reach):
            for seed in trials.seeds:
                trial = run_trial(description, factory, command, condition, seed, trials.seconds, ground)
                falls, count = falls + trial.fell, count + 1
                if not trial.fell and command[2] == 0.0:
                    aimed = np.asarray(command[:2]) * trials.seconds
                    strays.append(float(np.linalg.norm(np.asarray(trial.displacement) - aimed)))
    return {"falls": falls, "trials": count, "stray_m": float(np.mean(strays)) if strays else float("nan")}


def select_checkpoint(run_dir: Path, last: int, trials: SelectionTrials,
                      progress: Callable[[str, dict], None] | None = None) -> tuple[str, list[dict]]:
    """(the best of the run's ``last`` checkpoints by (falls, stray), every candidate's row: checkpoint, PPO env
    steps, falls, trials, stray_m). ``progress(name, row)`` after each."""
    from toddlerbot.rl import train
    from toddlerbot.rl.environment import training_description
    from toddlerbot.rl.environments import environment_class
    from toddlerbot.rl.export import export_run

    env_cfg, _ = train.load_config(run_dir)
    policy_name = environment_class(env_cfg.environment).runtime_policy
    if last < 1:
        raise ToddlerbotError(f"--select {last}: expected at least 1 checkpoint")
    candidates = train.checkpoint_paths(run_dir)[-last:]
    if not candidates:
        raise ToddlerbotError(f"{run_dir}: no checkpoint to select from")
    description = training_description(env_cfg)
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for path in candidates:
            exported = export_run(run_dir, Path(scratch) / f"{path.stem}.npz", description, checkpoint=path.name)
            row = {"checkpoint": path.name, "ppo_env_steps": train.checkpoint_env_steps(path),
                   **checkpoint_score(exported, policy_name, description, trials)}
            rows.append(row)
            if progress:
                progress(path.name, row)
    best = min(rows, key=lambda r: (r["falls"], np.nan_to_num(r["stray_m"], nan=np.inf)))
    return best["checkpoint"], rows
