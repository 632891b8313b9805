"""`rl train --reward-weight NAME=W`: a reward term's weight for a new run (checked, recorded, refused on a resume
and with a warm start), and runs saved before a term existed load with that term off."""

import json

import pytest

pytest.importorskip("jax")

from toddlerbot.errors import ToddlerbotError
from toddlerbot.rl import config, train
from toddlerbot.rl.launch import TrainRequest, new_run_plan, reward_weights
from toddlerbot.rl.rewards import WALK_REWARDS


def test_a_weight_is_set_by_name_and_the_others_keep_table_6():
    table = WALK_REWARDS.default_weights
    weights = reward_weights(table, TrainRequest(reward_weights=("path_xy=5", "survival=12.5")))
    assert weights == {**table, "path_xy": 5.0, "survival": 12.5}
    assert table["path_xy"] == 0.0  # the configuration itself is not changed


@pytest.mark.parametrize(("item", "message"), [
    ("path_xz=5", r"^--reward-weight path_xz=5: unknown reward term 'path_xz'; expected one of .*path_xy"),
    ("path_xy=-1", r"^--reward-weight path_xy=-1: expected NAME=WEIGHT with a weight in \[0, 10000\]$"),
    ("path_xy=nan", r"^--reward-weight path_xy=nan: expected NAME=WEIGHT with a weight in \[0, 10000\]$"),
    ("path_xy=1e9", r"^--reward-weight path_xy=1e9: expected NAME=WEIGHT with a weight in \[0, 10000\]$"),
    ("path_xy", r"^--reward-weight path_xy: expected NAME=WEIGHT"),
    ("path_xy=five", r"^--reward-weight path_xy=five: expected NAME=WEIGHT"),
])
def test_rl_train_refuses_a_bad_weight_in_one_line_and_writes_nothing(tmp_path, item, message):
    with pytest.raises(ToddlerbotError, match=message):
        new_run_plan(tmp_path / "bad", TrainRequest(smoke=True, reward_weights=(item,)))
    assert not (tmp_path / "bad").exists()


def test_a_new_run_trains_with_the_weight_and_a_warm_start_refuses_one(tmp_path):
    plan = new_run_plan(tmp_path / "run", TrainRequest(smoke=True, reward_weights=("path_xy=5",)))
    assert plan.env.reward.weights["path_xy"] == 5.0
    with pytest.raises(ToddlerbotError, match=r"^--warm-start: .*--reward-weight.* \(its critic learned the source"):
        new_run_plan(tmp_path / "warm", TrainRequest(warm_start=tmp_path / "run", reward_weights=("path_xy=5",)))


def test_a_run_saved_before_the_path_term_existed_loads_with_it_off(tmp_path):
    weighted = config.RewardConfig(weights={**WALK_REWARDS.default_weights, "path_xy": 5.0})
    env_cfg = config.EnvConfig(reward=weighted)
    train.save_config(tmp_path, env_cfg, config.SMOKE)
    assert train.load_config(tmp_path)[0].reward.weights["path_xy"] == 5.0  # saved, loaded back
    raw = json.loads((tmp_path / "config.json").read_text())
    del raw["env"]["reward"]["weights"]["path_xy"]  # as a run of an earlier version saved it
    (tmp_path / "config.json").write_text(json.dumps(raw))
    loaded = train.load_config(tmp_path)[0].reward.weights
    assert set(loaded) == set(WALK_REWARDS) and loaded["path_xy"] == 0.0 and loaded["survival"] == 10.0
