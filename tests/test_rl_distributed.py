"""``rl train`` on several JAX devices and over several processes (issue 45).

Two local devices are XLA's forced host devices (``--xla_force_host_platform_device_count=2``, set before JAX
starts, so in a subprocess); two processes are two ``rl train`` processes joined by ``jax.distributed`` on
127.0.0.1, exchanging gradients through gloo. Both train the tiny target task of `ppo_support` (registered as an
environment by `rl_distributed_support`), which compiles in seconds.
"""

import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("brax")

from cli_support import one_line_error, run_main
from rl_distributed_support import NAME, TINY, UPDATES_PER_EPOCH
from toddlerbot.rl.config import SMOKE_XLA_FLAGS

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src"
SEEDS = 4
FINAL_ERROR_TOLERANCE = 0.03
"""How far the mean final squared error (1 - step reward, the last 5 of 25 updates, over `SEEDS` seeds) on two
devices may be from one device's. Measured over 8 seeds: 0.205 +- 0.009 (one device), 0.207 +- 0.012 (two; mean
+- seed-to-seed standard deviation), so the difference of two 4-seed means has a standard error of about 0.0075: 0.03
is 4 of them. From the random policy's 0.67-1.1 both fall to about 0.2."""
PROCESS_TOLERANCE = 1e-6
"""Largest difference of a network parameter between two processes of one device each and one process of two
devices, the same global envs: the same envs and keys on each device, so the same arithmetic (measured: 0)."""


def _environment(devices: int) -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), str(SRC)]), "TODDLERBOT_COMPILE_CACHE": "off",
            "XLA_FLAGS": f"--xla_force_host_platform_device_count={devices} {SMOKE_XLA_FLAGS}"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _finish(processes: dict) -> dict:
    """Each process's output once all have ended (asserting that each succeeded)."""
    outputs = {}
    for name, process in processes.items():
        out, _ = process.communicate(timeout=600)
        assert process.returncode == 0, f"{name}:\n{out[-4000:]}"
        outputs[name] = out
    return outputs


@pytest.mark.slow
def test_two_devices_learn_as_one():
    """The same 16 envs on two devices (8 each, gradients and normaliser statistics averaged) learn as on one:
    the mean final error over 4 seeds agrees within `FINAL_ERROR_TOLERANCE`, and the devices' copies of the
    parameters stay identical."""
    script = f"from rl_distributed_support import print_learning_curves; print_learning_curves({SEEDS})"
    outputs = _finish({devices: subprocess.Popen([sys.executable, "-c", script], env=_environment(devices),
                                                 text=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
                       for devices in (1, 2)})
    results = {devices: json.loads(out.strip().splitlines()[-1]) for devices, out in outputs.items()}
    errors = {devices: 1 - np.array(r["step_reward"]) for devices, r in results.items()}
    final = {devices: e[:, -5:].mean(axis=1) for devices, e in errors.items()}
    print(f"final squared error over {SEEDS} seeds: one device {np.round(final[1], 4)}, two {np.round(final[2], 4)}")
    assert results[2]["devices"] == 2 and results[1]["devices"] == 1
    assert abs(final[2].mean() - final[1].mean()) < FINAL_ERROR_TOLERANCE
    for devices, e in errors.items():  # and both learned: the error at least halves from the random policy's
        assert np.all(final[devices] < 0.5 * e[:, 0]), (devices, e[:, 0], final[devices])
    assert results[2]["replica_spread"] == 0.0 and results[1]["replica_spread"] == 0.0


def _leaves(path: Path) -> list[np.ndarray]:
    with np.load(path) as saved:
        return [saved[f"arr_{i}"] for i in range(len(saved.files))]


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _train(tmp: Path, stage: str, *args: str) -> dict[str, str]:
    """Stage ``stage``: process 0 and 1 of a two-process run and a one-process run on two devices, at once; each
    keeps the state it ended with in ``tmp/<stage>-<name>.npz`` and runs in its own folder ``tmp/<name>``."""
    port = _free_port()
    joined = ["--coordinator", f"127.0.0.1:{port}", "--num-processes", "2", "--process-id"]
    commands = {"p0": [*args, *joined, "0"], "p1": [*args, *joined, "1"], "one": list(args)}
    run_dirs = {"p0": "run", "p1": "p1-run", "one": "one-run"}
    processes = {}
    for name, options in commands.items():
        (tmp / name).mkdir(exist_ok=True)
        options = [str(tmp / run_dirs[name]) if arg == "RUN" else arg for arg in options]
        processes[name] = subprocess.Popen(
            [sys.executable, str(TESTS / "rl_distributed_support.py"), str(tmp / f"{stage}-{name}.npz"), "rl", "train",
             *options], cwd=tmp / name, env=_environment(2 if name == "one" else 1), text=True,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    return _finish(processes)


@pytest.fixture(scope="module")
def first(tmp_path_factory):
    """A new two-process run of one epoch (process 1 told another folder: it must write nothing there), beside the
    same on one process of two devices: (folder, outputs, what process 1 wrote)."""
    tmp = tmp_path_factory.mktemp("distributed")
    outputs = _train(tmp, "first", "--env", NAME, "--smoke", "--backend", "mjx", "--epochs", "1",
                     "--no-tensorboard", "--out", "RUN")
    p1_wrote = [*_files(tmp / "p1"), *(["its --out folder"] if (tmp / "p1-run").exists() else [])]
    return tmp, outputs, p1_wrote


@pytest.fixture(scope="module")
def resumed(first):
    """`first`'s runs resumed for one more epoch, process 1 given a copy of the run (as on a machine without the
    shared folder): (folder, outputs, the copy's files before)."""
    tmp = first[0]
    shutil.copytree(tmp / "run", tmp / "p1-run")
    copy_before = _files(tmp / "p1-run")
    return tmp, _train(tmp, "resumed", "--resume", "RUN", "--epochs", "1", "--no-tensorboard"), copy_before


def _assert_same_state(tmp: Path, stage: str) -> None:
    p0, p1, one = (_leaves(tmp / f"{stage}-{name}.npz") for name in ("p0", "p1", "one"))
    assert all(np.array_equal(a, b) for a, b in zip(p0, p1, strict=True)), "the processes' states differ"
    largest = max(float(np.max(np.abs(a.astype(float) - b.astype(float)))) for a, b in zip(p0, one, strict=True))
    print(f"{stage}: largest difference from one process of two devices {largest:.3g}")
    assert largest <= PROCESS_TOLERANCE


@pytest.mark.slow
def test_two_processes_train_as_one_process_of_two_devices_and_only_process_0_writes(first):
    from toddlerbot.rl import train

    tmp, outputs, p1_wrote = first
    _assert_same_state(tmp, "first")
    assert "process 0 of 2" in outputs["p0"] and "process 1 of 2" in outputs["p1"]
    steps = UPDATES_PER_EPOCH * TINY.env_steps_per_update
    records = [json.loads(line) for line in (tmp / "run" / "metrics.jsonl").read_text().splitlines()]
    assert [r["env_steps"] for r in records] == [steps] and records[0]["device"] == "2 processes, each 1 x cpu"
    checkpoint, = train.checkpoint_paths(tmp / "run")
    state, _, _ = train.load_checkpoint(checkpoint, train.PPO(_target_task(), TINY).initial_state(_key()))
    import jax

    written = jax.tree.leaves((state.params, state.normalizer_params, state.env_steps))
    assert all(np.array_equal(a, b) for a, b in zip(written, _leaves(tmp / "first-p0.npz"), strict=True))
    assert p1_wrote == []  # nothing in its working folder, no folder where its --out pointed


@pytest.mark.slow
def test_a_two_process_run_resumes(resumed):
    from toddlerbot.rl import train

    tmp, outputs, copy_before = resumed
    _assert_same_state(tmp, "resumed")
    steps = UPDATES_PER_EPOCH * TINY.env_steps_per_update
    records = [json.loads(line) for line in (tmp / "run" / "metrics.jsonl").read_text().splitlines()]
    assert [r["env_steps"] for r in records] == [steps, 2 * steps]
    assert [train.checkpoint_env_steps(p) for p in train.checkpoint_paths(tmp / "run")] == [steps, 2 * steps]
    assert _files(tmp / "p1-run") == copy_before  # process 1 read its copy and wrote nothing
    assert f"done: {2 * steps:,} env steps" in outputs["p1"]


@pytest.mark.slow
def test_processes_given_different_options_stop_in_one_line(tmp_path):
    """Process 1 asks for 32 envs, process 0 for the recipe's 16: both stop before training, with one line."""
    port = _free_port()
    processes = {k: subprocess.Popen(
        [sys.executable, str(TESTS / "rl_distributed_support.py"), str(tmp_path / f"p{k}.npz"), "rl", "train", "--env",
         NAME, "--smoke", "--backend", "mjx", "--no-tensorboard", "--out", str(tmp_path / f"run{k}"), "--coordinator",
         f"127.0.0.1:{port}", "--num-processes", "2", "--process-id", str(k), *(["--num-envs", "32"] if k else [])],
        env=_environment(1), text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE) for k in (0, 1)}
    for k, process in processes.items():
        _, err = process.communicate(timeout=600)
        errors = [line for line in err.splitlines() if line.startswith("error:")]
        assert process.returncode == 2 and errors == [
            "error: process 1's training configuration differs from process 0's: give every process the same options "
            "(and, with --resume, the same run)"], (k, err[-3000:])
    assert not (tmp_path / "run0" / "checkpoints").exists() and not (tmp_path / "run1").exists()


def _target_task():
    from rl_distributed_support import TargetTask
    from toddlerbot.rl.config import EnvConfig

    return TargetTask(EnvConfig(environment=NAME))


def _key():
    import jax

    return jax.random.PRNGKey(0)


@pytest.mark.parametrize(("options", "message"), [
    (["--coordinator", "node001", "--num-processes", "2", "--process-id", "0"],
     "--coordinator node001: expected HOST:PORT (e.g. 10.0.0.1:1234 or node001:1234; a port in 1-65535), the address "
     "of process 0"),
    (["--coordinator", "127.0.0.1:70000", "--num-processes", "2", "--process-id", "0"],
     "--coordinator 127.0.0.1:70000: expected HOST:PORT"),
    (["--coordinator", "127.0.0.1:1234", "--num-processes", "2", "--process-id", "2"],
     "--process-id 2: expected 0 to 1 for 2 processes"),
    (["--coordinator", "127.0.0.1:1234", "--num-processes", "0", "--process-id", "0"],
     "--num-processes 0: expected at least 1"),
    (["--num-processes", "2", "--process-id", "1"],
     "--coordinator missing: --coordinator HOST:PORT, --num-processes N and --process-id K go together"),
])
def test_bad_process_options_are_one_line(monkeypatch, capsys, tmp_path, options, message):
    for name in ("SLURM_JOB_ID", "OMPI_MCA_orte_hnp_uri", "JAX_COORDINATOR_ADDRESS"):
        monkeypatch.delenv(name, raising=False)
    line = one_line_error(*run_main(monkeypatch, capsys, "rl", "train", "--smoke", "--out", tmp_path / "run",
                                    *options)[:3:2])
    assert line.startswith(f"error: {message}"), line
    assert not (tmp_path / "run").exists()


def test_several_processes_need_a_named_run_directory(monkeypatch, capsys):
    line = one_line_error(*run_main(monkeypatch, capsys, "rl", "train", "--smoke", "--coordinator",
                                    "127.0.0.1:1234", "--num-processes", "2", "--process-id", "0")[:3:2])
    assert line == ("error: --out: a run of several processes needs its run directory named (the same folder for "
                    "every process)")


def test_a_slurm_step_of_several_tasks_joins_and_one_of_one_task_does_not(monkeypatch):
    """Under `srun` the processes' variables are SLURM's (read by jax.distributed itself); a step of one task, or
    --num-processes 1, stays a single process; a --process-id is checked against the step's task count."""
    from toddlerbot.errors import ToddlerbotError
    from toddlerbot.rl.distributed import Processes

    for name, value in {"SLURM_JOB_ID": "77", "SLURM_STEP_NODELIST": "node[001-002]", "SLURM_NTASKS": "8",
                        "SLURM_PROCID": "3", "SLURM_LOCALID": "3"}.items():
        monkeypatch.setenv(name, value)
    assert Processes().wanted() and Processes(coordinator="node001:4321").wanted()
    assert not Processes(num_processes=1).wanted()
    with pytest.raises(ToddlerbotError, match=r"^--process-id 8: expected 0 to 7 for 8 processes$"):
        Processes(process_id=8)
    monkeypatch.setenv("SLURM_NTASKS", "1")
    assert not Processes().wanted()
    monkeypatch.setenv("SLURM_NTASKS", "eight")
    with pytest.raises(ToddlerbotError, match=r"^SLURM_NTASKS=eight: expected a number of processes$"):
        Processes().wanted()


def test_a_process_waits_for_its_coordinator_and_gives_up_in_one_line():
    """Process K > 0 waits until process 0's coordinator answers (here at once: a listening socket), and stops with
    one line when nothing answers in time (JAX itself would abort the process with a stack trace)."""
    from toddlerbot.errors import ToddlerbotError
    from toddlerbot.rl.distributed import wait_for_coordinator

    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        wait_for_coordinator(f"127.0.0.1:{server.getsockname()[1]}", 5.0)
    port = _free_port()
    with pytest.raises(ToddlerbotError, match=rf"^--coordinator 127.0.0.1:{port}: nothing answered there in 1 s "
                                              r"\(.+\); start process 0 on that machine"):
        wait_for_coordinator(f"127.0.0.1:{port}", 1.0)
