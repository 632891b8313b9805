"""The shipped terrain policy (`walk_rl_terrain.npz`, docs/rl.md "The 1 cm recipe over three training seeds"): found
by name, its file records the recipe and the training seed that made it, and on 1 cm tiles it falls on fewer of the
reach's walks than the flat-floor default, which falls on most walks that leave the start square."""

from pathlib import Path

import pytest

from toddlerbot.policies import make_policy
from toddlerbot.policies.rl_inference import RLPolicyFile
from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS, resolve_weights, shipped_names
from toddlerbot.runtime.robustness import conditions, reach_commands, run_trial
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.terrain import parse_terrain

TILES = parse_terrain("rough:height=0.01")
SEED = 103
"""A ground and robot seed that neither training, selection (1000-1001) nor the benchmark's figures (100-102) used."""


def test_the_terrain_policy_ships_by_name_with_its_recipe_in_its_metadata():
    path = resolve_weights("walk_rl_terrain")
    assert path == DEFAULT_WEIGHTS.parent / "walk_rl_terrain.npz"
    assert {"walk_rl", "walk_rl_gpu", "walk_rl_terrain"} <= set(shipped_names())  # what --weights' help lists
    meta = RLPolicyFile(path).meta
    assert meta["terrain_stages"] == [[0, "rough:height=0.01,cell=0.1", 1]]
    assert meta["terrain_start_stages"] == [[0, 0.08]]
    assert meta["reward_weights"]["lin_vel_xy"] == 10.0 and meta["imitation_iterations"] == 3
    assert meta["ppo_env_steps"] == 78 * 51_200 and meta["seed"] == 2  # the seed the declared rule picked
    assert Path(meta["init_policy"]).name == "walk_rl.npz"


def _falls(description, weights: str) -> int:
    factory = lambda robot: make_policy("walk-rl", robot, weights=weights)  # noqa: E731
    nominal = conditions()[0]
    reach = factory(MuJoCoRobot(description)).command_reach
    return sum(run_trial(description, factory, command, nominal, SEED, 10.0, TILES).fell
               for command in reach_commands(reach))


@pytest.mark.slow
def test_on_1_cm_tiles_the_terrain_policy_falls_on_fewer_walks_than_the_flat_floor_default(description):
    # measured on this seed: terrain policy 1 of 10 (0.15 m/s forward), flat-floor default 6 of 10
    assert _falls(description, "walk_rl_terrain") <= 3
    assert _falls(description, "walk_rl") >= 4
