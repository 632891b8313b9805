import json
import subprocess
import sys
from dataclasses import replace

import mujoco
import pytest
import typer
from typer.testing import CliRunner

from toddlerbot.cli.main import app

runner = CliRunner()


def _command_paths(command, prefix=()):
    yield prefix
    for name, sub in getattr(command, "commands", {}).items():
        yield from _command_paths(sub, (*prefix, name))


@pytest.mark.parametrize("path", list(_command_paths(typer.main.get_command(app))), ids=" ".join)
def test_every_command_has_help(path):
    result = runner.invoke(app, [*path, "--help"])
    assert result.exit_code == 0, result.output
    assert "Usage" in result.output


def test_model_build_is_byte_identical_across_runs(tmp_path):
    a, b = tmp_path / "a.xml", tmp_path / "b.xml"
    for path in (a, b):
        result = runner.invoke(app, ["model", "build", "--variant", "gripper", "--scene", "-o", str(path)])
        assert result.exit_code == 0, result.output
    assert a.read_bytes() == b.read_bytes()
    model = mujoco.MjModel.from_xml_path(str(a))
    assert model.nu == 32 and model.geom("floor").id >= 0


def test_model_info_prints_mass_height_and_motor_table():
    result = runner.invoke(app, ["model", "info"])
    assert result.exit_code == 0, result.output
    assert "total mass 3.358 kg" in result.output
    assert "standing height 0.553 m" in result.output
    assert "left_knee_drive" in result.output and "XM430-W210" in result.output


def test_bad_spec_is_one_line_error_without_traceback(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nbodies: []\n")
    proc = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", "model", "info", "--spec", str(bad)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "bad.yaml" in proc.stderr and "Traceback" not in proc.stderr


def test_unknown_variant_is_a_usage_error():
    result = runner.invoke(app, ["model", "build", "--variant", "wings", "-o", "x.xml"])
    assert result.exit_code == 2
    assert "wings" in result.output


def test_model_build_uses_fitted_motor_params(tmp_path):
    params = tmp_path / "xc330.json"
    params.write_text('{"motor": "XC330", "actuator": {"armature": 0.0123, "damping": 0.0456}}')
    out = tmp_path / "robot.xml"
    result = runner.invoke(app, ["model", "build", "--motor-params", str(params), "-o", str(out)])
    assert result.exit_code == 0, result.output
    model = mujoco.MjModel.from_xml_path(str(out))
    neck = model.joint("neck_yaw_drive")
    assert model.dof_armature[neck.dofadr[0]] == pytest.approx(0.0123)
    assert model.dof_damping[neck.dofadr[0]] == pytest.approx(0.0456)
    knee = model.joint("left_knee_drive")  # an XM430: unchanged
    assert model.dof_armature[knee.dofadr[0]] == pytest.approx(0.0022)


def _main(args, monkeypatch, capsys):
    from toddlerbot.cli import main as cli_main

    monkeypatch.setattr(sys, "argv", ["toddlerbot", *args])
    with pytest.raises(SystemExit) as exit_:
        cli_main.main()
    return exit_.value.code, *capsys.readouterr()


def test_a_chain_that_fails_its_success_check_exits_1(tmp_path, monkeypatch, capsys):
    chain = tmp_path / "still.yaml"
    chain.write_text("name: still\nscene: wagon\nsuccess:\n  moved: {body: wagon, at_least: 0.5}\n"
                     "skills:\n  - {name: wait, kind: hold, until: {after: 0.1}}\n")
    code, out, err = _main(["chain", "run", "wagon", "--chain", str(chain), "--json"], monkeypatch, capsys)
    outcome = json.loads(out)
    assert code == 1 and err == ""
    assert outcome["success"] is False and outcome["wagon_displacement_m"] < 0.01


def test_an_evaluation_with_falls_exits_1_and_its_json_holds_no_nan(monkeypatch, capsys):
    import numpy as np

    from toddlerbot.runtime import tracking

    fell = tracking.TrackingResult(position_m=float("nan"), lin_vel_mps=0.1, ang_vel_radps=0.2, falls=1,
                                   duration_s=3.0, time=np.zeros(1), command=np.zeros((1, 3)),
                                   achieved=np.zeros((1, 3)))
    monkeypatch.setattr(tracking, "evaluate_policy", lambda *args: fell)
    code, out, _ = _main(["eval", "tracking", "--policy", "walk-zmp", "--json"], monkeypatch, capsys)
    assert code == 1
    assert json.loads(out) == {"position_m": None, "lin_vel_mps": 0.1, "ang_vel_radps": 0.2, "falls": 1,
                               "duration_s": 3.0}
    monkeypatch.setattr(tracking, "evaluate_policy", lambda *args: replace(fell, falls=0, position_m=0.05))
    code, out, _ = _main(["eval", "tracking", "--policy", "walk-zmp"], monkeypatch, capsys)
    assert code == 0 and "falls 0" in out
