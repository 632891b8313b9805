"""The diffusion policy on the pick task end to end: `manip demo` dataset -> `dp train` -> `dp eval`."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("av")
pytest.importorskip("pyarrow")

from typer.testing import CliRunner  # noqa: E402

from toddlerbot.cli.main import app  # noqa: E402
from toddlerbot.dp import evaluate as dp_evaluate  # noqa: E402
from toddlerbot.dp import shipped  # noqa: E402
from toddlerbot.dp.checkpoint import load_policy  # noqa: E402
from toddlerbot.dp.data import open_window_dataset  # noqa: E402

runner = CliRunner()
TRAIN_STEPS = 100


@pytest.fixture(scope="module")
def pick_run(tmp_path_factory):
    """A 2-episode scripted pick dataset (the fewest that split into training and validation) and a tiny policy
    trained on it through the CLI."""
    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("dp_pick")
    dataset, run = root / "ds", root / "run"
    result = runner.invoke(app, ["manip", "demo", "--task", "pick", "--episodes", "2", "--seed", "4242",
                                 "-o", str(dataset)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(app, ["dp", "train", str(dataset), "-o", str(run), "--config", "tiny",
                                 "--steps", str(TRAIN_STEPS), "--threads", "1"])
    assert result.exit_code == 0, result.output
    return dataset, run


@pytest.mark.slow
def test_dp_train_reads_a_manip_demo_dataset_and_the_loss_falls(pick_run):
    dataset, run = pick_run
    windows = open_window_dataset(dataset, 2, 16)
    sample = windows[0]
    assert sample["observation.images.head"].shape == (2, 3, 96, 96)
    assert sample["observation.images.head"].dtype == np.uint8
    assert sample["observation.state"].shape == (2, 16) and sample["action"].shape == (16, 16)
    assert sorted(set(windows.window_episodes.tolist())) == [0, 1]
    split = json.loads((run / "split.json").read_text())
    assert len(split["train_episodes"]) == 1 and len(split["val_episodes"]) == 1  # split by episode
    history = json.loads((run / "metrics.json").read_text())
    assert [h["step"] for h in history] == [50, 100]
    assert history[-1]["train_loss"] < 0.8 * history[0]["train_loss"]
    config = load_policy(run / "checkpoint.pt").config
    info = json.loads((dataset / "meta/info.json").read_text())
    assert list(config.state_names) == info["features"]["action"]["names"]  # joint names travel with the weights


@pytest.mark.slow
def test_dp_eval_runs_the_trained_checkpoint_on_the_pick_task(pick_run, monkeypatch):
    _, run = pick_run
    episodes = []
    run_episode = dp_evaluate.run_episode

    def spy(*args, **kwargs):
        episodes.append(run_episode(*args, **kwargs))
        return episodes[-1]

    monkeypatch.setattr(dp_evaluate, "run_episode", spy)
    result = runner.invoke(app, ["dp", "eval", "--task", "pick", "--checkpoint", str(run / "checkpoint.pt"),
                                 "--episodes", "2", "--seed", "1000", "--seconds", "1.0", "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["episodes"] == 2 and [e.seed for e in episodes] == [1000, 1001]
    assert 0.0 <= summary["success_rate"] <= 1.0 and summary["success_rate"] == np.mean([e.success for e in episodes])
    assert summary["inference_ms"] > 0
    for episode in episodes:
        # 1 s at 50 Hz: chunks asked for at steps 0 and 25, each used from 0.3 s after its observation (15, 40)...
        assert episode.chunks_used == 2
        # ...and the commanded targets are the policy's, not the held start pose
        assert episode.max_target_offset > 0.01


@pytest.mark.parametrize(("steps", "success_after", "frames"), [(12, None, 3), (10, None, 2), (12, 6, 2)])
def test_dp_eval_video_has_a_frame_per_policy_tick_and_none_after_the_last_step(steps, success_after, frames):
    from types import SimpleNamespace

    task = SimpleNamespace(head_image=lambda: np.zeros((96, 96, 3), np.uint8), succeeded=False)
    video = SimpleNamespace(frames=0)
    video.add = lambda image: setattr(video, "frames", video.frames + 1)
    observer = dp_evaluate.PolicyTickVideo(task, video, every=5, steps=steps)  # ticks at steps 0, 5, 10
    observer.on_start(None, None, None)
    for index in range(steps):
        task.succeeded = index == success_after  # the run stops after this step
        observer.on_step(SimpleNamespace(index=index))
        if task.succeeded:
            break
    assert video.frames == frames


def test_dp_eval_without_a_checkpoint_says_none_is_shipped(tmp_path, monkeypatch):
    monkeypatch.setattr(shipped, "SHIPPED_DIR", tmp_path)
    result = runner.invoke(app, ["dp", "eval", "--task", "pick", "--episodes", "1"])
    assert isinstance(result.exception, shipped.NoShippedCheckpointError)
    message = str(result.exception)
    assert "\n" not in message and "no trained checkpoint is shipped for task 'pick'" in message
    assert str(tmp_path / "pick.pt") in message


def test_dp_eval_refuses_a_checkpoint_made_for_other_joints(tmp_path):
    from types import SimpleNamespace

    from toddlerbot.dp.checkpoint import new_training_state, save_checkpoint
    from toddlerbot.dp.config import TINY

    path = save_checkpoint(tmp_path / "other.pt", new_training_state(TINY.with_dims(3, 2)))
    result = runner.invoke(app, ["dp", "eval", "--checkpoint", str(path), "--episodes", "1"])
    assert isinstance(result.exception, dp_evaluate.EvalError)
    assert str(result.exception) == "checkpoint has state 3 / action 2 dimensions; task 'pick' records 16 motors"
    names = tuple(f"motor_{i}" for i in range(16))
    task = SimpleNamespace(name="pick", space=SimpleNamespace(names=names))
    dp_evaluate.check_fits(TINY.with_dims(16, 16, names, names), task)  # same joints: accepted
    renamed = (*names[:-1], "left_gripper_drive")
    with pytest.raises(dp_evaluate.EvalError, match=r"checkpoint action names .* differ from task 'pick'"):
        dp_evaluate.check_fits(TINY.with_dims(16, 16, names, renamed), task)


def test_dp_export_keeps_the_ema_network_and_drops_the_training_state(tmp_path):
    from toddlerbot.dp.checkpoint import (
        CheckpointError,
        load_training_state,
        new_training_state,
        save_checkpoint,
    )
    from toddlerbot.dp.config import TINY

    state = new_training_state(TINY.with_dims(3, 2))
    for p in state.ema.model.parameters():  # EMA weights that differ from the raw network's
        p.data.add_(0.5)
    full = save_checkpoint(tmp_path / "checkpoint.pt", state)
    result = runner.invoke(app, ["dp", "export", str(full), "-o", str(tmp_path / "policy.pt")])
    assert result.exit_code == 0, result.output
    exported = tmp_path / "policy.pt"
    assert exported.stat().st_size < 0.5 * full.stat().st_size  # no raw weights, no AdamW moments
    kept, original = load_policy(exported).state_dict(), state.ema.model.state_dict()
    assert kept.keys() == original.keys() and all(torch.equal(kept[k], original[k]) for k in kept)
    with pytest.raises(CheckpointError, match=r"exported policy .* cannot resume training"):
        load_training_state(exported)


def test_the_shipped_pick_policy_fits_the_pick_task():
    from types import SimpleNamespace

    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.tasks.space import ManipulationSpace

    path = shipped.shipped_checkpoint("pick")
    assert path.stat().st_size < 8e6  # small enough for the package
    config = load_policy(path).config
    space = ManipulationSpace.of(RobotDescription.load(variant="gripper"))
    dp_evaluate.check_fits(config, SimpleNamespace(name="pick", space=space))
    assert (config.encoder, config.down_dims, config.inference_steps) == ("small_cnn", (32, 64, 128), 3)
