"""``dp train`` under torchrun: two gloo processes learn what one process learns with the same global batch, and
rank 0 alone writes the run directory (docs/manipulation.md, "Training on several GPUs or machines")."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from typer.testing import CliRunner  # noqa: E402

from toddlerbot.cli.main import app  # noqa: E402
from toddlerbot.datasets.dataset import IMAGE_KEY, Dataset, save_decoded  # noqa: E402
from toddlerbot.dp.checkpoint import load_policy, load_training_state  # noqa: E402
from toddlerbot.dp.config import DPConfigError  # noqa: E402
from toddlerbot.dp.data import gather, open_window_dataset  # noqa: E402
from toddlerbot.dp.distributed import batch_rows  # noqa: E402
from toddlerbot.dp.policy import IMAGE, STATE  # noqa: E402

STEPS, LOG_EVERY = 30, 5
LOSS_TOLERANCE = 1e-5
"""Largest relative difference between the one- and two-process loss curves. Measured: at most 1.3e-7 (float32
rounding): the two runs see the same windows, noise and steps and the same global mean, but sum them in a
different order (two half-batch sums, then gloo's all-reduce), which Adam carries on from step to step."""

# Each rank runs the CLI (as `torchrun ... -m toddlerbot.cli.main dp train ...` would) and then saves the weights it
# ended with, so the test can compare rank 1's weights (which no file holds) with rank 0's checkpoint.
WORKER = textwrap.dedent("""
    import os, sys
    import torch
    from toddlerbot.cli import main as cli
    from toddlerbot.dp import train

    states, new_state = [], train.new_training_state

    def kept(*args, **kwargs):
        states.append(new_state(*args, **kwargs))
        return states[-1]

    train.new_training_state = kept
    weights_dir = sys.argv.pop(1)
    try:
        cli.main()
    except SystemExit as exc:
        code = exc.code
    if states:
        torch.save({"model": states[0].policy.state_dict(), "ema": states[0].ema.model.state_dict()},
                   os.path.join(weights_dir, f"rank{os.environ['RANK']}.pt"))
    sys.exit(code)
""")


def write_dataset(path: Path, episodes: int = 6, frames: int = 12, size: int = 24) -> Path:
    """A decoded dataset of random-walk joint angles; the head image's brightness is the first angle."""
    rng = np.random.default_rng(0)
    n = episodes * frames
    state = np.cumsum(rng.normal(0.0, 0.05, (n, 2)), axis=0).astype(np.float32)
    action = (state + 0.1 * np.sin(np.arange(n))[:, None]).astype(np.float32)
    level = np.round(255 * (state[:, 0] - state[:, 0].min()) / np.ptp(state[:, 0])).astype(np.uint8)
    images = np.broadcast_to(level[:, None, None, None], (n, size, size, 3)).copy()
    starts = np.arange(episodes) * frames
    info = {"codebase_version": "v3.0", "fps": 10,
            "features": {"action": {"names": ["joint_a", "joint_b"]}, IMAGE_KEY: {"shape": [size, size, 3]}}}
    dataset = Dataset(Path("synthetic"), info, state, action, np.tile(np.arange(frames) / 10.0, episodes),
                      np.repeat(np.arange(episodes), frames), images, np.stack([starts, starts + frames], axis=1),
                      ("pick",), {})
    return save_decoded(dataset, path)


def torchrun(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    worker = tmp_path / "worker.py"
    worker.write_text(WORKER)
    env = {k: v for k, v in os.environ.items() if k not in ("RANK", "WORLD_SIZE", "LOCAL_RANK")}
    env["OMP_NUM_THREADS"] = "1"
    return subprocess.run([sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2",
                           str(worker), str(tmp_path), *args], capture_output=True, text=True, env=env, timeout=180)


def _train_args(dataset: Path, run: Path) -> list[str]:
    return ["dp", "train", str(dataset), "-o", str(run), "--config", "tiny", "--threads", "1", "--steps", str(STEPS),
            "--log-every", str(LOG_EVERY)]


def test_two_gloo_processes_learn_what_one_process_learns_and_only_rank_0_writes(tmp_path):
    dataset = write_dataset(tmp_path / "ds.npz")
    run = torchrun(tmp_path, *_train_args(dataset, tmp_path / "ddp"))
    assert run.returncode == 0, run.stderr[-3000:]
    printed = " ".join(run.stdout.split())  # rank 0 alone prints
    assert printed.count(": 72 windows; run directory") == 1 and printed.count(f"step {STEPS}: train loss") == 1
    single = CliRunner().invoke(app, _train_args(dataset, tmp_path / "one"))
    assert single.exit_code == 0, single.output

    ddp = json.loads((tmp_path / "ddp" / "metrics.json").read_text())
    one = json.loads((tmp_path / "one" / "metrics.json").read_text())
    assert [r["step"] for r in ddp] == [r["step"] for r in one] == list(range(LOG_EVERY, STEPS + 1, LOG_EVERY))
    for key in ("train_loss", "val_loss"):
        a, b = np.array([r[key] for r in ddp]), np.array([r[key] for r in one])
        assert np.max(np.abs(a - b) / b) < LOSS_TOLERANCE, (key, a, b)
    assert one[-1]["train_loss"] < one[0]["train_loss"] / 2  # a curve that learns, not a flat one

    # one set of run files, written by rank 0: one record per step in metrics.jsonl, one TensorBoard event file
    files = sorted(p.relative_to(tmp_path / "ddp").as_posix() for p in (tmp_path / "ddp").rglob("*") if p.is_file())
    assert [f for f in files if not f.startswith("tensorboard/")] == [
        "checkpoint.pt", "config.json", "loss_curve.png", "metrics.json", "metrics.jsonl", "split.json"]
    assert len([f for f in files if f.startswith("tensorboard/")]) == 1
    assert [json.loads(line)["step"] for line in (tmp_path / "ddp" / "metrics.jsonl").read_text().splitlines()] == \
        [r["step"] for r in ddp]

    # the checkpoint holds the weights every rank ended with (rank 1's come from the worker)
    state = load_training_state(tmp_path / "ddp" / "checkpoint.pt")
    assert state.step == STEPS and state.ema.updates == STEPS
    ranks = [torch.load(tmp_path / f"rank{r}.pt", weights_only=True) for r in (0, 1)]
    for name, tensor in state.policy.state_dict().items():
        assert torch.equal(tensor, ranks[1]["model"][name]) and torch.equal(tensor, ranks[0]["model"][name]), name
    for name, tensor in state.ema.model.state_dict().items():
        assert torch.equal(tensor, ranks[1]["ema"][name]), name
    # and they act as one process's network does: the same chunks for every window (measured: at most 3.3e-7 apart,
    # of a 1.16 action range). The weights themselves are not compared: where the output does not depend on a
    # weight (the first convolution's bias ahead of its GroupNorm), its gradient is 0 up to rounding, which Adam
    # scales to full-size steps, so such weights drift apart (measured: 0.013) with no effect on the output.
    windows = open_window_dataset(dataset, 2, 16)
    observed = gather(windows, range(len(windows)), (STATE, IMAGE))
    chunks = [load_policy(tmp_path / run / "checkpoint.pt").sample(observed, torch.Generator().manual_seed(3))
              for run in ("ddp", "one")]
    assert float((chunks[0] - chunks[1]).abs().max()) < 1e-4

def test_a_batch_that_does_not_split_over_the_processes_is_refused_before_anything_is_written(tmp_path):
    assert batch_rows(16, 2, 1) == slice(8, 16) and batch_rows(16, 1, 0) == slice(0, 16)
    with pytest.raises(DPConfigError, match="batch size 15 does not split evenly over 2 processes"):
        batch_rows(15, 2, 0)
    run = torchrun(tmp_path, "dp", "train", str(write_dataset(tmp_path / "ds.npz")), "-o", str(tmp_path / "ddp"),
                   "--config", "tiny", "--threads", "1", "--steps", "1", "--batch-size", "15")
    assert run.returncode != 0
    assert "error: batch size 15 does not split evenly over 2 processes (WORLD_SIZE); give a --batch-size divisible " \
           "by 2" in " ".join(run.stderr.split())
    assert not (tmp_path / "ddp").exists()
