"""The RL environment is built from one `RobotDescription`: derived objects built once, fitted actuator
parameters (``--motor-params``) reach the simulated robot and are recorded. No JIT compilation here."""

import json

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("mujoco.mjx")

from typer.testing import CliRunner

import toddlerbot.rl.model as rl_model
import toddlerbot.robot.builder as builder
import toddlerbot.robot.description as description_module
from toddlerbot.cli.main import app
from toddlerbot.rl import randomization
from toddlerbot.rl.config import EnvConfig, smoke_env_config
from toddlerbot.rl.reference import standing_table
from toddlerbot.rl.run_files import motor_params_record
from toddlerbot.rl.walk_env import WalkEnv
from toddlerbot.robot.description import RobotDescription

KNEE_MODEL = "XM430-W210"


def _reference(description):
    return standing_table(description, smoke_env_config().command, period=0.6)


_GAINS = (np.ones(30), np.zeros((2, 30)))
"""P-gain factors given like the reference (walk-zmp's would build its generator and compile its models)."""


def test_building_the_env_builds_each_derived_object_once(monkeypatch):
    counts = {"load_spec": 0, "build_transmission_map": 0, "build_mjspec": 0}

    def counting(module, name):
        original = getattr(module, name)

        def wrapper(*args, **kwargs):
            counts[name] += 1
            return original(*args, **kwargs)

        monkeypatch.setattr(module, name, wrapper)

    counting(description_module, "load_spec")
    counting(description_module, "build_transmission_map")
    counting(rl_model, "build_mjspec")
    compiles = []
    original_build_model = builder.build_model
    monkeypatch.setattr(builder, "build_model", lambda *a, **k: compiles.append(1) or original_build_model(*a, **k))

    description = RobotDescription.load()
    env = WalkEnv(EnvConfig(), description, reference=_reference(description), gain_scales=_GAINS)
    assert env.description is description
    assert counts == {"load_spec": 1, "build_transmission_map": 1, "build_mjspec": 1}
    assert compiles == []  # the training variant is the only compiled model (not the simulator's as well)
    assert env.mj_model.nu == description.n_motors


def _params_file(tmp_path, **actuator):
    path = tmp_path / "params.json"
    path.write_text(json.dumps({"motor": KNEE_MODEL, "actuator": actuator, "fitted": sorted(actuator)}))
    return path


def test_motor_params_change_what_the_env_simulates(tmp_path):
    path = _params_file(tmp_path, damping=0.02, armature=0.005, tau_max=2.5, q_dot_max=9.0)
    nominal_description = RobotDescription.load()
    nominal = WalkEnv(EnvConfig(backend="cpu"), nominal_description, reference=_reference(nominal_description),
                      gain_scales=_GAINS)
    cfg = EnvConfig(motor_params=(str(path),), backend="cpu")
    fitted = WalkEnv(cfg, reference=_reference(nominal_description), gain_scales=_GAINS)
    assert fitted.description.motor_params_files == (str(path),)
    knees = np.array([i for i, m in enumerate(fitted.description.motors) if m.model == KNEE_MODEL])
    others = np.setdiff1d(np.arange(fitted.n_motors), knees)
    assert len(knees) >= 4
    # the actuator model the env applies every substep ...
    np.testing.assert_allclose(np.asarray(fitted.actuators.tau_max)[knees], 2.5)
    np.testing.assert_allclose(np.asarray(fitted.actuators.q_dot_max)[knees], 9.0)
    np.testing.assert_array_equal(np.asarray(fitted.actuators.tau_max)[others],
                                  np.asarray(nominal.actuators.tau_max)[others])
    assert not np.allclose(np.asarray(nominal.actuators.tau_max)[knees], 2.5)
    # ... and the joint damping / armature of the training model both backends step (the CPU backend's nominal
    # fields, what domain randomisation then scales)
    dofs = fitted.motor_dadr[knees]
    for fields in (fitted.physics._nominal, {k: np.asarray(v) for k, v in fitted.model_fields(
            randomization.nominal(fitted.mj_model.nv, fitted.mj_model.nbody, fitted.n_motors)).items()}):
        np.testing.assert_allclose(fields["dof_damping"][dofs], 0.02, rtol=1e-6)
        np.testing.assert_allclose(fields["dof_armature"][dofs], 0.005, rtol=1e-6)
    assert not np.allclose(nominal.mj_model.dof_damping[dofs], 0.02)
    # the record a run and its export keep
    record = motor_params_record(cfg.motor_params)
    assert record[0]["file"] == str(path) and len(record[0]["sha256"]) == 64
    assert record[0]["params"]["actuator"]["tau_max"] == 2.5


def test_description_must_match_the_configs_motor_params(tmp_path):
    path = _params_file(tmp_path, damping=0.02)
    description = RobotDescription.load()
    with pytest.raises(ValueError, match="motor params"):
        WalkEnv(EnvConfig(motor_params=(str(path),)), description, reference=_reference(description),
                gain_scales=_GAINS)


def test_cli_rejects_a_bad_params_file_in_one_line_before_compiling(tmp_path):
    bad = tmp_path / "params.json"
    bad.write_text(json.dumps({"motor": KNEE_MODEL, "actuator": {"tau_max": "strong"}}))
    result = CliRunner().invoke(app, ["rl", "train", "--smoke", "--out", str(tmp_path / "run"),
                                      "--motor-params", str(bad)])
    assert result.exit_code != 0
    message = str(result.exception)
    assert str(bad) in message and "tau_max" in message and "\n" not in message
    assert not (tmp_path / "run" / "config.json").exists()


def test_cli_rejects_zero_solver_iterations_in_one_line(tmp_path):
    result = CliRunner().invoke(app, ["rl", "train", "--smoke", "--out", str(tmp_path / "run"),
                                      "--solver-iterations", "0"])
    assert result.exit_code != 0
    assert "solver iterations 0/8: expected 1-100" in str(result.exception)
