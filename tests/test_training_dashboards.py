"""Training dashboards: one `MetricsLogger` sends each record to the JSON lines, TensorBoard and (``--wandb``) W&B.

The event files are read back with TensorBoard's own reader; W&B is a fake module that records its calls (the
real package is large and not installed for the tests). The RL side is checked on the smoke run of
`test_rl_train_smoke.py` (no second training run); a tiny `dp train` runs here.
"""

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dashboard_support import (
    as_float32,
    expected_scalars,
    fake_wandb,
    numbers,
    read_jsonl,
    read_scalars,
    wandb_logs,
)
from toddlerbot.errors import ToddlerbotError
from toddlerbot.metrics import TENSORBOARD_DIR, WANDB_RUN_ID, Dashboards, MetricsLogger

pytest.importorskip("tensorboardX")
pytest.importorskip("tensorboard")
SRC = Path(__file__).resolve().parents[1] / "src"

RECORDS = [
    {"iteration": 1, "env_steps": 100, "bc_loss": 0.5, "teacher_drives": True, "device": "CPU"},
    {"iteration": 2, "env_steps": 200, "bc_loss": 0.25, "teacher_drives": False, "device": "CPU"},
]
EPOCHS = [{"env_steps": 50, "kl_mean": 0.01, "learning_rate": 3e-4, "val": None},
          {"env_steps": 100, "kl_mean": 0.02, "learning_rate": 2e-4, "val": None}]


def _log_run(run, dashboards, epochs=EPOCHS):
    with MetricsLogger.open(run, {"dagger": "imitation.jsonl", "ppo": "metrics.jsonl"}, dashboards,
                            job_type="test", config={"lr": 1e-3}) as logger:
        for r in RECORDS:
            logger.log("dagger", r, step=r["env_steps"])
        for r in epochs:
            logger.log("ppo", r, step=200 + r["env_steps"])


def test_one_logger_sends_the_same_scalars_and_steps_to_every_sink(tmp_path, monkeypatch):
    wandb = fake_wandb(monkeypatch)
    _log_run(tmp_path, Dashboards(wandb=True, wandb_mode="offline"))
    # JSON lines: whole records, labels included
    assert read_jsonl(tmp_path / "imitation.jsonl") == RECORDS and read_jsonl(tmp_path / "metrics.jsonl") == EPOCHS
    # TensorBoard: the numbers only (no booleans, strings, None), at the given steps
    scalars = read_scalars(tmp_path / TENSORBOARD_DIR)
    expected = {**expected_scalars("dagger", RECORDS, [100, 200]), **expected_scalars("ppo", EPOCHS, [250, 300])}
    assert scalars == expected
    assert "dagger/teacher_drives" not in scalars and "ppo/val" not in scalars
    # W&B: one run, the same numbers, each stream against its own step
    names = [name for name, _ in wandb.CALLS]
    assert names[0] == "init" and names[-1] == "finish" and names.count("init") == 1
    init = wandb.CALLS[0][1]
    assert init["mode"] == "offline" and init["dir"] == str(tmp_path) and init["resume"] == "allow"
    assert init["id"] == (tmp_path / WANDB_RUN_ID).read_text().strip() and init["config"] == {"lr": 1e-3}
    assert ("define_metric", {"name": "ppo/*", "step_metric": "ppo/step"}) in wandb.CALLS
    assert ("define_metric", {"name": "dagger/*", "step_metric": "dagger/step"}) in wandb.CALLS
    assert wandb_logs(wandb.CALLS, "dagger") == [{**numbers(r), "step": r["env_steps"]} for r in RECORDS]
    assert wandb_logs(wandb.CALLS, "ppo") == [{**numbers(r), "step": 200 + r["env_steps"]} for r in EPOCHS]
    assert wandb.CALLS[-1] == ("finish", {"exit_code": 0})


def test_a_resumed_run_adds_to_the_same_tensorboard_folder_and_wandb_run(tmp_path, monkeypatch):
    wandb = fake_wandb(monkeypatch)
    _log_run(tmp_path, Dashboards(wandb=True), EPOCHS[:1])
    _log_run(tmp_path, Dashboards(wandb=True), EPOCHS[1:])
    inits = [kw for name, kw in wandb.CALLS if name == "init"]
    assert len(inits) == 2 and inits[0]["id"] == inits[1]["id"]  # the W&B run continues
    assert inits[0]["mode"] is None  # no --wandb-mode: WANDB_MODE or W&B's default decides
    assert len(list((tmp_path / TENSORBOARD_DIR).iterdir())) == 2  # one event file per training call
    assert read_scalars(tmp_path / TENSORBOARD_DIR)["ppo/kl_mean"] == [(250, as_float32(0.01)),
                                                                       (300, as_float32(0.02))]


def test_a_failed_training_closes_every_sink(tmp_path, monkeypatch):
    wandb = fake_wandb(monkeypatch)
    with pytest.raises(RuntimeError), MetricsLogger.open(tmp_path, {"ppo": "m.jsonl"}, Dashboards(wandb=True)) as m:
        m.log("ppo", {"loss": 1.0}, step=1)
        raise RuntimeError("diverged")
    assert wandb.CALLS[-1] == ("finish", {"exit_code": 1})
    assert read_scalars(tmp_path / TENSORBOARD_DIR) == {"ppo/loss": [(1, 1.0)]}  # flushed


def test_json_lines_only(tmp_path):
    with MetricsLogger.open(tmp_path, {"ppo": "m.jsonl"}, Dashboards(tensorboard=False)) as logger:
        logger.log("ppo", {"loss": 1.0}, step=1)
    assert read_jsonl(tmp_path / "m.jsonl") == [{"loss": 1.0}] and not (tmp_path / TENSORBOARD_DIR).exists()


@pytest.mark.skipif(importlib.util.find_spec("torch") is None, reason="tensorboardX loads PyTorch only where installed")
def test_tensorboard_logging_does_not_load_pytorch(tmp_path):
    """tensorboardX's writer imports PyTorch whenever it is installed (1.0 s and 191 MB, docs/rl.md); RL training
    must not need it nor pay for it: the trainer's modules and a TensorBoard sink leave it unloaded, and the scalar
    written reads back."""
    trainer = "import toddlerbot.rl.train; " if importlib.util.find_spec("jax") else ""  # extra [train]
    code = (f"import sys; {trainer}from toddlerbot.metrics import MetricsLogger; "
            f"m = MetricsLogger.open({str(tmp_path)!r}, {{}}); m.log('ppo', {{'kl_mean': 0.0123}}, 7); m.close(); "
            "print(sorted(name for name in sys.modules if name.split('.')[0] == 'torch'), "
            "'tensorboardX' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(SRC)})
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.splitlines()[-1].split() == ["[]", "True"]  # (MJX prints a line of its own on import)
    assert read_scalars(tmp_path / TENSORBOARD_DIR) == {"ppo/kl_mean": [(7, as_float32(0.0123))]}


def test_wandb_without_the_package_and_bad_modes_are_one_line_errors(monkeypatch):
    monkeypatch.setitem(sys.modules, "wandb", None)  # as if not installed
    with pytest.raises(ToddlerbotError, match=r"--wandb needs the wandb package.*toddlerbot\[wandb\]"):
        Dashboards(wandb=True).check()
    with pytest.raises(ToddlerbotError, match="--wandb-mode 'cloud': expected online or offline"):
        Dashboards(wandb=True, wandb_mode="cloud")
    Dashboards(tensorboard=False).check()  # nothing else needs it


def _main(args, monkeypatch, capsys):
    from toddlerbot.cli import main as cli_main

    monkeypatch.setattr(sys, "argv", ["toddlerbot", *args])
    with pytest.raises(SystemExit) as exit_:
        cli_main.main()
    return exit_.value.code, *capsys.readouterr()


@pytest.mark.parametrize("area", ["rl", "dp"])
def test_train_with_wandb_but_without_the_package_fails_at_once_in_one_line(area, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "wandb", None)
    args = ["rl", "train", "--smoke", "--out", str(tmp_path / "run")] if area == "rl" else \
        ["dp", "train", str(tmp_path / "ds"), "-o", str(tmp_path / "run"), "--steps", "1"]
    code, out, err = _main([*args, "--wandb"], monkeypatch, capsys)
    assert code == 2 and "Traceback" not in out + err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "--wandb needs the wandb package" in lines[0] and "toddlerbot[wandb]" in lines[0]
    assert not (tmp_path / "run").exists()  # refused before anything was written or compiled


def test_wandb_mode_needs_wandb(tmp_path, monkeypatch, capsys):
    code, _, err = _main(["dp", "train", str(tmp_path / "ds"), "-o", str(tmp_path / "run"), "--steps", "1",
                          "--wandb-mode", "offline"], monkeypatch, capsys)
    assert code == 2 and "add --wandb" in err and len(err.strip().splitlines()) == 1


# a tiny dp train through the CLI -------------------------------------------------------------------------------
def _dp_train(tmp_path, monkeypatch, steps, *options):
    pytest.importorskip("torch")
    from typer.testing import CliRunner

    from dp_support import SyntheticWindows
    from toddlerbot.cli.main import app
    from toddlerbot.dp import data

    monkeypatch.setattr(data, "open_window_dataset", lambda *_: SyntheticWindows(episodes=3, frames=5))
    run = tmp_path / "run"
    result = CliRunner().invoke(app, ["dp", "train", str(tmp_path / "ds"), "-o", str(run), "--config", "tiny",
                                      "--threads", "1", "--steps", str(steps), *options])
    assert result.exit_code == 0, result.output
    return run


def test_dp_train_writes_its_records_to_tensorboard_and_wandb(tmp_path, monkeypatch):
    wandb = fake_wandb(monkeypatch)
    run = _dp_train(tmp_path, monkeypatch, 101, "--wandb", "--wandb-mode", "offline")
    records = read_jsonl(run / "metrics.jsonl")
    assert [r["step"] for r in records] == [50, 100, 101]  # every 50 steps and the last one
    assert records == json.loads((run / "metrics.json").read_text())  # the history, written as it came
    for r in records:
        assert r["train_loss"] > 0 and r["val_loss"] > 0 and r["learning_rate"] == 1e-3 and r["steps_per_s"] > 0
    scalars = read_scalars(run / TENSORBOARD_DIR)
    assert scalars == expected_scalars("dp", records, [50, 100, 101])
    for tag in ("dp/train_loss", "dp/val_loss", "dp/learning_rate", "dp/steps_per_s", "dp/seconds"):
        assert len(scalars[tag]) == 3, tag
    assert wandb_logs(wandb.CALLS, "dp") == [{**numbers(r), "step": r["step"]} for r in records]
    init = wandb.CALLS[0][1]
    assert init["job_type"] == "dp-train" and init["mode"] == "offline" and init["config"]["horizon"] == 16


def test_dp_train_without_tensorboard(tmp_path, monkeypatch):
    run = _dp_train(tmp_path, monkeypatch, 2, "--no-tensorboard")
    assert not (run / TENSORBOARD_DIR).exists() and len(read_jsonl(run / "metrics.jsonl")) == 1
