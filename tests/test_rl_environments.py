"""RL environments are registered bundles (`toddlerbot.rl.environments`): `walk` is one registration, and a second
one registered by a script trains through the same `rl train` path with its own configuration, rewards and recipe."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("jax")
pytest.importorskip("brax")

from cli_support import one_line_error, run_main
from rl_env_support import NAME, STAND_REWARDS, StandEnv, register
from toddlerbot.errors import ToddlerbotError
from toddlerbot.rl import config, rewards, train
from toddlerbot.rl.environments import ENVIRONMENTS, environment_class
from toddlerbot.rl.launch import TrainRequest, new_run_plan
from toddlerbot.rl.walk_env import WalkEnv

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src"
TRAIN_STAND = """
import sys
from pathlib import Path
from rl_env_support import NAME, register
from toddlerbot.rl.launch import TrainRequest, new_run_plan
from toddlerbot.rl.train import train
register()
plan = new_run_plan(Path(sys.argv[1]), TrainRequest(smoke=True, environment=NAME, imitation_iterations=0))
train(plan.run_dir, plan.env, plan.ppo, imitation_cfg=plan.imitation, max_epochs=1)
"""


def test_walk_is_registered_with_its_bundle():
    walk = environment_class("walk")
    assert walk is WalkEnv and "walk" in ENVIRONMENTS.names()
    assert walk.reward_terms is rewards.WALK_REWARDS and walk.reward_terms.default_weights["survival"] == 10.0
    assert walk.recipe("cpu").ppo == config.CPU and walk.recipe("cpu").imitation == config.CPU_IMITATION
    assert walk.recipe("mjx").ppo == config.FULL and walk.recipe("mjx").imitation.iterations == 0
    assert walk.recipe("cpu", smoke=True).ppo == config.SMOKE
    assert walk.default_config().environment == "walk" and walk.default_config(smoke=True).obs.history == 3


def test_an_unknown_or_misnamed_environment_is_one_line(monkeypatch, capsys, tmp_path):
    line = one_line_error(*run_main(monkeypatch, capsys, "rl", "train", "--env", "swim", "--smoke", "--out",
                                    tmp_path / "run")[:3:2])
    assert line == "error: unknown environment 'swim'; expected one of walk, track" + (", " + NAME if NAME in
                                                                                ENVIRONMENTS.names() else "")
    assert not (tmp_path / "run").exists()
    ENVIRONMENTS.register("misnamed-test", StandEnv) if "misnamed-test" not in ENVIRONMENTS else None
    with pytest.raises(ToddlerbotError, match=r"^environment 'misnamed-test': its class StandEnv is named "
                                              r"'stand-test'; expected 'misnamed-test'$"):
        environment_class("misnamed-test")


def test_an_environment_refuses_another_ones_configuration():
    register()
    with pytest.raises(ValueError, match=r"the 'walk' environment takes a EnvConfig of environment 'walk'"):
        WalkEnv.resolved_config(StandEnv.default_config())


def test_a_registered_environment_trains_with_its_own_config_rewards_and_recipe(tmp_path):
    """The script-registered `stand-test` environment trains one smoke epoch on the CPU backend: the run records its
    name, its three reward weights and its stand-only commands, reloads as its configuration, and its step reward
    stays within its own table's bound (survival 10 x 0.02 s; walk's table would allow 0.6)."""
    register()
    run = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), str(SRC)]),
           "XLA_FLAGS": config.SMOKE_XLA_FLAGS}
    out = subprocess.run([sys.executable, "-c", TRAIN_STAND, str(run)], env=env, capture_output=True, text=True,
                         timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    saved = json.loads((run / "config.json").read_text())["env"]
    assert saved["environment"] == NAME and saved["reward"]["weights"] == STAND_REWARDS.default_weights
    assert saved["command"]["stand_prob"] == 1.0 and saved["backend"] == "cpu"
    env_cfg, ppo_cfg = train.load_config(run)
    assert env_cfg.environment == NAME and ppo_cfg == config.SMOKE
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert len(records) == 1 and records[0]["env_steps"] == config.SMOKE.env_steps_per_update
    assert -0.05 < records[0]["step_reward"] <= 10.0 * env_cfg.ctrl_dt + 1e-6
    with pytest.raises(ToddlerbotError, match=r"^--env: a resumed run keeps the settings it started with"):
        from toddlerbot.rl.launch import resume_plan

        resume_plan(run, TrainRequest(environment="walk"))


def test_a_warm_start_of_another_environment_is_refused(tmp_path):
    register()
    walk_run = tmp_path / "walk"
    plan = new_run_plan(walk_run, TrainRequest(smoke=True))
    train.save_config(walk_run, plan.env, plan.ppo, plan.imitation)
    (walk_run / "warm_start.msgpack").write_bytes(b"x")
    with pytest.raises(ToddlerbotError, match=rf"^--warm-start {walk_run}: a run of environment 'walk'; "
                                              rf"expected '{NAME}'$"):
        new_run_plan(tmp_path / "stand", TrainRequest(warm_start=walk_run, environment=NAME))
