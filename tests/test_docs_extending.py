"""docs/extending.md stays correct: its Python blocks run, in order, in one namespace (they assert their own
figures: the catalogue entry loads, a fitted params.json reaches the description, the example policy nods the
head by the commanded amount, the example variant adds exactly its mass and is registered for `--variant`, the
example task's demonstrator reaches its marker, the example skill turns the head by the commanded amount in a
chain), and its policy and its task, installed as it says, run from the command line."""

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.runtime.log import RunLog

DOC = Path(__file__).resolve().parents[1] / "docs" / "extending.md"


@pytest.fixture
def restored_tasks(monkeypatch):
    """The task the guide registers, only for the test."""
    from toddlerbot.tasks import TASKS

    TASKS.names()
    monkeypatch.setattr(TASKS, "_targets", dict(TASKS._targets))
    monkeypatch.setattr(TASKS, "_resolved", dict(TASKS._resolved))


@pytest.fixture
def restored_motor_models(monkeypatch):
    """The actuator model the guide registers, only for the test."""
    from toddlerbot.actuation.motor_models import MOTOR_MODELS

    MOTOR_MODELS.names()
    monkeypatch.setattr(MOTOR_MODELS, "_targets", dict(MOTOR_MODELS._targets))
    monkeypatch.setattr(MOTOR_MODELS, "_resolved", dict(MOTOR_MODELS._resolved))


@pytest.fixture
def restored_skills(monkeypatch):
    """The skill kinds the guide registers last only for the test (as `restored_registries` does for policies)."""
    from toddlerbot.skills import SKILLS

    SKILLS.names()
    monkeypatch.setattr(SKILLS, "_targets", dict(SKILLS._targets))
    monkeypatch.setattr(SKILLS, "_resolved", dict(SKILLS._resolved))


def test_every_python_block_of_the_extending_guide_runs(tmp_path, monkeypatch, restored_registries, restored_skills,
                                                        restored_tasks, restored_motor_models):
    blocks = re.findall(r"^```python\n(.*?)^```", DOC.read_text(), flags=re.S | re.M)
    assert len(blocks) == 12  # motor model (3), actuator model (2), policy (2), variant (1), task (2), skill (2)
    monkeypatch.chdir(tmp_path)  # the blocks write their example files to the current folder
    namespace: dict = {"__name__": "extending_guide"}
    for number, block in enumerate(blocks, 1):
        exec(compile(block, f"{DOC.name} python block {number}", "exec"), namespace)
    assert namespace["swing"] > 0.4 and namespace["extra_kg"] > 0.19 and namespace["turned"] > 0.35
    from toddlerbot.skills import SKILLS

    assert "look" in SKILLS  # registered by the guide, for chain files
    assert namespace["progress"].succeeded and namespace["reach"].distance() < 0.02
    assert abs(namespace["fitted"].torque_limit - 0.6) < 0.01


def _block(language: str, containing: str) -> str:
    blocks = re.findall(rf"^```{language}\n(.*?)^```", DOC.read_text(), flags=re.S | re.M)
    (block,) = [b for b in blocks if containing in b]
    return block


def _installed(tmp_path: Path, module: str, containing: str, group: str, toml: str | None = None):
    """The guide's block `containing` as `module`.py with the guide's pyproject entry points of `group` (or those
    of `toml`), installed as pip installs them (the module beside a dist-info folder whose entry_points.txt lists the
    group): a function running ``toddlerbot ARGS`` in a process that sees them."""
    (tmp_path / f"{module}.py").write_text(_block("python", containing))
    groups = tomllib.loads(toml or _block("toml", group))["project"]["entry-points"]
    dist_info = tmp_path / f"{module}-0.1.dist-info"
    dist_info.mkdir()
    (dist_info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (dist_info / "entry_points.txt").write_text("".join(
        f"[{name}]\n" + "".join(f"{point} = {value}\n" for point, value in points.items())
        for name, points in groups.items()))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}

    def toddlerbot(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", *args], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=300)

    return toddlerbot


def test_a_policy_installed_as_the_guide_says_runs_from_the_command_line(tmp_path):
    """The guide's policy module and its pyproject entry point make `sim run --policy nod` nod the head."""
    toddlerbot = _installed(tmp_path, "my_policies", "class NodPolicy", "toddlerbot.policies")
    run = toddlerbot("sim", "run", "--policy", "nod", "--seconds", "2", "--log", "nod.npz")
    assert run.returncode == 0, run.stdout + run.stderr
    log = RunLog.load(tmp_path / "nod.npz")
    swing = np.ptp(log.joint_pos[:, log.joint_names.index("neck_pitch")])
    assert 0.4 < swing < 0.65 and len(log.time) == 100  # 0.6 rad commanded peak to peak; 2 s at 50 Hz
    unknown = toddlerbot("sim", "run", "--policy", "fly")
    assert unknown.returncode == 2
    expected = "expected one of stand, replay, walk-zmp, walk-rl, dp, get-up, track, nod"
    assert expected in " ".join(unknown.stderr.split())


def test_a_task_added_as_the_guide_says_is_one_file_and_one_registration_that_every_command_knows(tmp_path):
    """The guide's task file and its one entry point: its demonstrator succeeds over seeds (`manip demo-rate`), a
    chain in its scene starts where the task says and runs (`chain run`), `sim run --task` and teleoperation put the
    robot in its scene (the torso mounted: no walking), and unknown names are refused naming it."""
    import json

    toddlerbot = _installed(tmp_path, "my_tasks", "class ReachTask", "toddlerbot.tasks")
    rate = toddlerbot("manip", "demo-rate", "--task", "reach", "--episodes", "3", "--seed", "10", "--json")
    assert rate.returncode == 0, rate.stderr
    assert json.loads(rate.stdout)["success_rate"] == 1.0
    (tmp_path / "hold.yaml").write_text("name: hold_still\nscene: reach\nskills:\n"
                                        "  - {name: hold, kind: hold, hold: [arm], until: {after: 0.5}}\n")
    chain = toddlerbot("chain", "run", "hold.yaml", "--seed", "4", "--json")
    assert chain.returncode == 0, chain.stderr
    outcome = json.loads(chain.stdout)
    assert outcome["success"] and outcome["sim_seconds"] == 0.5 and outcome["driven_by"] == {"hold": "hold"}
    run = toddlerbot("sim", "run", "--task", "reach", "--policy", "stand", "--seconds", "0.5")
    assert run.returncode == 0 and "reach: not succeeded" in run.stdout, run.stdout + run.stderr
    teleop = subprocess.run([sys.executable, "-c", "from toddlerbot.teleop.launch import sim_robot\n"
                             "setup = sim_robot('reach', 2)\nprint(type(setup.robot).__name__, setup.walks, "
                             "setup.head_image().shape)"], cwd=tmp_path, capture_output=True, text=True,
                            env={**os.environ, "PYTHONPATH": str(tmp_path)}, timeout=300)
    assert teleop.stdout.split() == ["TaskRobot", "False", "(96,", "96,", "3)"], teleop.stderr
    unknown = toddlerbot("manip", "demo-rate", "--task", "kitchen")
    known = " ".join(unknown.stderr.split()).partition("expected one of ")[2]
    assert unknown.returncode == 2 and set(known.split(", ")) == {"pick", "wagon", "reach"}


def test_an_actuator_model_added_as_the_guide_says_fits_and_simulates_from_the_command_line(tmp_path):
    """The guide's actuator model, one file and one entry point: `sysid excite --simulate` with its parameters
    writes logs, `sysid fit --model linear` recovers them, and `sim run --motor-params` walks a robot whose XC330s
    are of it; a catalogue or params.json naming an unknown model is one line naming the registered ones."""
    import json

    (tmp_path / "pyproject.toml").write_text('[project.entry-points."toddlerbot.motor_models"]\n'
                                             'linear = "my_motor_model:LinearParams"\n')
    toddlerbot = _installed(tmp_path, "my_motor_model", "class _LinearModel", "toddlerbot.motor_models",
                            toml=(tmp_path / "pyproject.toml").read_text())
    truth = {"model": "linear", "damping": 0.004, "armature": 0.004, "frictionloss": 0.03,
             "stiffness_per_kp": 1 / 150, "torque_limit": 0.6}
    (tmp_path / "truth.json").write_text(json.dumps({"motor": "XC330", "actuator": truth}))
    steps = [("sysid", "excite", "--motor", "XC330", "-o", "runs", "--profile", "chirp", "--profile", "steps",
              "--profile", "sinusoids", "--kp", "100", "--kp", "400", "--duration", "4", "--rig",
              '{"type": "pendulum", "mass": 0.49, "length": 0.1}', "--simulate", "--params", "truth.json"),
             ("sysid", "fit", "runs/manifest.json", "--model", "linear", "--evals", "1200", "-o", "fitted.json"),
             ("sim", "run", "--policy", "walk-zmp", "--seconds", "3", "--motor-params", "fitted.json")]
    for args in steps:
        done = toddlerbot(*args)
        assert done.returncode == 0, (args, done.stdout + done.stderr)
    fitted = json.loads((tmp_path / "fitted.json").read_text())["actuator"]
    assert fitted["model"] == "linear" and abs(fitted["torque_limit"] - 0.6) < 0.01
    assert "no fall" in done.stdout
    (tmp_path / "bad.json").write_text(json.dumps({"motor": "XC330", "actuator": {**truth, "model": "cubic"}}))
    unknown = toddlerbot("model", "info", "--motor-params", "bad.json")
    assert unknown.returncode == 2 and "unknown actuator model 'cubic'; expected one of appendix, dc_motor, linear" \
        in " ".join(unknown.stderr.split())
