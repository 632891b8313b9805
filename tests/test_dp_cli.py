"""``toddlerbot dp train``: trains through the dataset adapter, resumes, and refuses bad input in one line."""

import json

import pytest

torch = pytest.importorskip("torch")

from typer.testing import CliRunner  # noqa: E402

from dp_support import SyntheticWindows  # noqa: E402
from toddlerbot.cli.main import app  # noqa: E402
from toddlerbot.dp import data  # noqa: E402
from toddlerbot.dp.checkpoint import CheckpointError, load_policy, load_training_state  # noqa: E402
from toddlerbot.dp.data import DatasetError  # noqa: E402
from toddlerbot.errors import ToddlerbotError  # noqa: E402

runner = CliRunner()


def test_dp_train_runs_through_the_dataset_adapter_and_resumes(tmp_path, monkeypatch):
    opened = []

    def fake_reader(path, n_obs_steps, horizon):
        opened.append((path.name, n_obs_steps, horizon))
        return SyntheticWindows(episodes=3, frames=5)

    monkeypatch.setattr(data, "open_window_dataset", fake_reader)
    run = tmp_path / "run"
    args = ["dp", "train", str(tmp_path / "ds"), "-o", str(run), "--config", "tiny", "--threads", "1"]
    result = runner.invoke(app, [*args, "--steps", "3"])
    assert result.exit_code == 0, result.output
    assert opened == [("ds", 2, 16)]  # observation history 2, horizon 16
    assert load_training_state(run / "checkpoint.pt").step == 3
    again = runner.invoke(app, [*args, "--steps", "3"])  # without --resume: refuse to overwrite the run
    assert isinstance(again.exception, CheckpointError) and "resume it (--resume)" in str(again.exception)
    result = runner.invoke(app, [*args, "--steps", "5", "--resume"])
    assert result.exit_code == 0, result.output
    assert load_training_state(run / "checkpoint.pt").step == 5 and "step 5" in result.output
    result = runner.invoke(app, ["dp", "info", str(run / "checkpoint.pt"), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    policy = load_policy(run / "checkpoint.pt")
    assert summary["step"] == 5 and summary["parameters"] == sum(p.numel() for p in policy.parameters())
    assert summary["config"]["state_names"] == ["joint_0", "joint_1", "joint_2"]
    assert summary["last"]["step"] == 5 and summary["last"]["train_loss"] > 0


def test_dp_train_names_a_missing_dataset_directory(tmp_path):
    result = runner.invoke(app, ["dp", "train", str(tmp_path / "nowhere"), "-o", str(tmp_path / "r"), "--steps", "1",
                                 "--threads", "1"])  # the CLI sets torch's threads for the whole process
    assert isinstance(result.exception, DatasetError)
    assert "nowhere: expected a dataset directory or a decoded .npz" in str(result.exception)
    assert not (tmp_path / "r").exists()  # nothing half-written


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the refusal on a machine without a CUDA GPU")
def test_dp_train_on_a_missing_gpu_is_refused_before_anything_is_written(tmp_path, monkeypatch):
    monkeypatch.setattr(data, "open_window_dataset", lambda *_: SyntheticWindows(episodes=3, frames=5))
    result = runner.invoke(app, ["dp", "train", str(tmp_path / "ds"), "-o", str(tmp_path / "r"), "--steps", "1",
                                 "--config", "tiny", "--threads", "1", "--device", "cuda"])
    assert "device 'cuda'" in str(result.exception) and "sees no CUDA GPU" in str(result.exception)
    assert not (tmp_path / "r").exists()


def test_dp_train_seed_gives_a_new_run_other_weights_and_a_resumed_run_refuses_it(tmp_path, monkeypatch):
    monkeypatch.setattr(data, "open_window_dataset", lambda *_: SyntheticWindows(episodes=3, frames=5))
    weights = {}
    for seed in (None, 0, 1):
        run = tmp_path / f"run_{seed}"
        args = ["dp", "train", str(tmp_path / "ds"), "-o", str(run), "--config", "tiny", "--threads", "1",
                "--steps", "1"] + ([] if seed is None else ["--seed", str(seed)])
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        state = load_training_state(run / "checkpoint.pt")
        assert state.policy.config.seed == (0 if seed is None else seed)
        weights[seed] = torch.cat([p.flatten() for p in load_policy(run / "checkpoint.pt").parameters()])
    assert torch.equal(weights[None], weights[0])  # the preset's seed is 0
    assert (weights[0] - weights[1]).abs().max() > 1e-3
    result = runner.invoke(app, ["dp", "train", str(tmp_path / "ds"), "-o", str(tmp_path / "run_1"), "--config",
                                 "tiny", "--threads", "1", "--steps", "2", "--resume", "--seed", "2"])
    assert isinstance(result.exception, ToddlerbotError)
    assert str(result.exception) == "--seed sets a new run's seed; a resumed run keeps its own (drop --seed)"
    assert load_training_state(tmp_path / "run_1" / "checkpoint.pt").step == 1  # untouched


def test_dp_train_and_export_binary_actions_by_name(tmp_path, monkeypatch):
    monkeypatch.setattr(data, "open_window_dataset", lambda *_: SyntheticWindows(episodes=3, frames=5))
    args = ["dp", "train", str(tmp_path / "ds"), "--config", "tiny", "--threads", "1", "--steps", "1"]
    result = runner.invoke(app, [*args, "-o", str(tmp_path / "run"), "--binary-action", "target_1"])
    assert result.exit_code == 0, result.output
    assert load_policy(tmp_path / "run" / "checkpoint.pt").config.binary_actions == ("target_1",)
    result = runner.invoke(app, [*args, "-o", str(tmp_path / "bad"), "--binary-action", "gripper"])
    assert "binary_actions ['gripper'] (expected distinct action names, of target_0, target_1)" in str(
        result.exception)
    assert not (tmp_path / "bad").exists()  # refused before anything is written
    result = runner.invoke(app, [*args, "-o", str(tmp_path / "run"), "--resume", "--binary-action", "target_0"])
    assert str(result.exception) == ("--binary-action sets a new run's binary action; a resumed run keeps its own "
                                     "(drop --binary-action)")
    out = tmp_path / "both.pt"
    result = runner.invoke(app, ["dp", "export", str(tmp_path / "run" / "checkpoint.pt"), "-o", str(out),
                                 "--binary-action", "target_0", "--binary-action", "target_1"])
    assert result.exit_code == 0, result.output
    assert load_policy(out).config.binary_actions == ("target_0", "target_1")


def test_dp_eval_prints_what_each_failed_episode_ended_in(capsys):
    from pathlib import Path

    from toddlerbot.cli.dp import _print_evaluation

    summary = {"success_rate": 0.5, "failed_seeds": [8001], "inference_ms": 12.34,
               "failures": {"8001": "home start: left closed off the bar, right open"}}
    _print_evaluation(summary, "wagon:wide", 8000, 2, Path("run/checkpoint.pt"))
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("wagon:wide: success 50% over seeds 8000..8001 (failed: [8001]), 12.3 ms")
    assert lines[1] == "  seed 8001: home start: left closed off the bar, right open"
