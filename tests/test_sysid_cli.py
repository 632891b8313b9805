"""`toddlerbot sysid` and `toddlerbot actuator` end to end on synthetic logs; params.json into the catalogue."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.params_file import catalogue_with_params, load_params
from toddlerbot.cli.main import app
from toddlerbot.errors import ParamsError
from toddlerbot.robot.builder import build_mjspec
from toddlerbot.robot.spec import load_spec
from toddlerbot.sysid.errors import SysIDError

runner = CliRunner()


def _ok(args: list[str]) -> str:
    result = runner.invoke(app, args, catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.output


def test_excite_fit_eval(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    _ok(["sysid", "excite", "-o", str(logs), "--motor", "XC330", "--profile", "steps", "--profile", "chirp",
         "--kp", "900", "--duration", "2", "--simulate", "--noise-deg", "0.1", "--seed", "4"])
    manifest = json.loads((logs / "manifest.json").read_text())
    assert manifest["motor"] == "XC330-T288" and manifest["rig"]["type"] == "pendulum"
    assert [e["file"] for e in manifest["logs"]] == ["steps_kp900.csv", "chirp_kp900.csv"]
    assert (logs / "steps_kp900.csv").read_text().splitlines()[0] == "time,goal_position,position"

    params = tmp_path / "params.json"
    _ok(["sysid", "fit", str(logs / "manifest.json"), "-o", str(params), "--evals", "64", "--seed", "2"])
    body = json.loads(params.read_text())
    assert body["motor"] == "XC330-T288" and body["fit"]["evals"] == 64
    # the default model is the DC motor (started from the XC330's appendix values), every fitted parameter with
    # a standard error, the gain conversion kept with its reason
    assert body["actuator"]["model"] == body["fit"]["model"] == "dc_motor" and len(body["fitted"]) == 7
    assert set(body["fit"]["uncertainty"]) == set(body["fitted"]) and "pwm_per_rad" in body["fit"]["fixed"]
    assert all(u["std"] > 0 for u in body["fit"]["uncertainty"].values())
    assert not list(tmp_path.glob(".params*"))  # no temp file left behind

    out = json.loads(_ok(["sysid", "eval", str(logs / "manifest.json"), str(params), "--json",
                          "--plot", str(tmp_path / "plots")]))
    assert set(out) == {"mae_deg", "rmse_deg", "runs"}
    assert [r["file"] for r in out["runs"]] == ["steps_kp900.csv", "chirp_kp900.csv"]
    assert all(set(r) == {"file", "mae_deg", "rmse_deg", "kp"} and r["kp"] == 900 for r in out["runs"])
    assert np.mean([r["mae_deg"] for r in out["runs"]]) == pytest.approx(out["mae_deg"], rel=0.01)  # equal lengths
    assert out["rmse_deg"] >= out["mae_deg"] > 0
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == ["chirp_kp900.png", "steps_kp900.png"]


def test_fit_bad_manifest_writes_nothing(tmp_path: Path) -> None:
    (tmp_path / "m.json").write_text(json.dumps({"motor": "XC330", "rig": {"type": "pendulum", "mass": 0.5,
                                                                           "length": 0.1},
                                                 "logs": [{"file": "missing.csv", "kp": 400}]}))
    with pytest.raises(SysIDError, match=r"missing\.csv"):
        runner.invoke(app, ["sysid", "fit", str(tmp_path / "m.json"), "-o", str(tmp_path / "p.json")],
                      catch_exceptions=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json"]


def test_params_load_into_catalogue_and_model(tmp_path: Path) -> None:
    path = tmp_path / "xm.json"
    path.write_text(json.dumps({"motor": "XM430", "actuator": {"armature": 0.0031, "damping": 0.007}}))
    name, params = load_params(path)
    assert name == "XM430-W210" and params.armature == 0.0031 and params.tau_max == 1.61  # others from catalogue
    catalogue = catalogue_with_params([path])
    model = build_mjspec(load_spec(), "fixed", catalogue=catalogue).compile()
    knee = model.joint("left_knee_drive").dofadr[0]  # an XM430 motor joint
    assert model.dof_armature[knee] == pytest.approx(0.0031) and model.dof_damping[knee] == pytest.approx(0.007)
    assert default_catalogue()["XM430"].actuator.armature == 0.0022  # the packaged catalogue is untouched
    path.write_text(json.dumps({"motor": "XM430", "actuator": {"armature": -1}}))
    with pytest.raises(ParamsError, match=r"xm.json: armature must be a finite number >= 0"):
        load_params(path)


def test_testbed_cli(tmp_path: Path) -> None:
    speed = np.repeat([1.0, 2.0, 3.0, -1.0, -2.0, -3.0], 5)
    torque = 0.05 * np.sign(speed) + 0.004 * speed
    (tmp_path / "bd.csv").write_text("speed,torque\n" + "".join(f"{s},{t}\n" for s, t in zip(speed, torque,
                                                                                               strict=True)))
    out = json.loads(_ok(["sysid", "testbed", "friction", str(tmp_path / "bd.csv"), "--json"]))
    assert out["frictionloss"] == pytest.approx(0.05) and out["damping"] == pytest.approx(0.004)
    assert out["directions"]["positive"]["r2"] == pytest.approx(1.0)


def test_actuator_plot_and_show(tmp_path: Path) -> None:
    from PIL import Image

    _ok(["actuator", "plot", "--motor", "XC330", "-o", str(tmp_path / "fig12.png")])
    image = np.asarray(Image.open(tmp_path / "fig12.png").convert("RGB")).astype(int)
    assert image.shape == (504, 1320, 3)  # 11 x 4.2 in at 120 dpi
    curve = np.abs(image - np.array([31, 119, 180])).max(axis=2) < 30  # matplotlib's C0 blue
    # both panels draw their blue curve: tau_limit over speed (left) and the envelope's bounds (right);
    # measured 1307 and 2192 pixels
    assert curve[:, :660].sum() > 500 and curve[:, 660:].sum() > 500
    out = json.loads(_ok(["actuator", "show", "--motor", "2XL430", "--json"]))
    assert out["motor"] == "2XL430-W250" and out["actuator"]["tau_brake"] == 1.40
