"""One `RobotDescription` per command: the spec is parsed once, the transmission map built once and each MuJoCo
model compiled once per (base, scene); importing the CLI (``--help``) parses no spec."""

import json
import subprocess
import sys
from collections import Counter

import mujoco
import pytest
from typer.testing import CliRunner

import toddlerbot.robot.builder as builder
import toddlerbot.robot.spec as spec_module
import toddlerbot.robot.transmission as transmission_module
from toddlerbot.cli.main import app


def _count_calls(monkeypatch: pytest.MonkeyPatch, module, name: str, calls: list) -> None:
    """Wrap ``module.name`` and every already-imported toddlerbot module's reference to it, recording each call's
    arguments; modules imported later pick up the wrapper from `module`."""
    original = getattr(module, name)

    def counting(*args, **kwargs):
        calls.append((args, kwargs))
        return original(*args, **kwargs)

    for mod_name, mod in list(sys.modules.items()):
        if mod_name.startswith("toddlerbot") and getattr(mod, name, None) is original:
            monkeypatch.setattr(mod, name, counting)


def test_sim_run_walk_zmp_derives_each_object_once(monkeypatch, tmp_path):
    specs, maps, models, compiles = [], [], [], []
    _count_calls(monkeypatch, spec_module, "_validate", specs)  # every load_spec / with_variant parses through it
    _count_calls(monkeypatch, transmission_module, "build_transmission_map", maps)
    _count_calls(monkeypatch, builder, "compile_robot", models)
    original_compile = mujoco.MjSpec.compile

    def counting_compile(self, *args, **kwargs):
        compiles.append(self)
        return original_compile(self, *args, **kwargs)

    monkeypatch.setattr(mujoco.MjSpec, "compile", counting_compile)
    out = tmp_path / "summary.json"
    result = CliRunner().invoke(app, ["sim", "run", "--policy", "walk-zmp", "--seconds", "0.2",
                                      "--summary-json", str(out)])
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text())["duration_s"] == pytest.approx(0.2)
    assert len(specs) == 1
    assert len(maps) == 1
    bases = Counter((args[1], args[2]) for args, _ in models)
    assert bases == {("floating", True): 1, ("fixed", False): 1}  # simulator; leg IK of the gait generator
    assert len(compiles) == 2


@pytest.mark.parametrize("command", [
    ["sim", "run", "--policy", "stand", "--seconds", "0.1"],
    ["eval", "tracking", "--policy", "walk-zmp", "--commands", "0:0,0,0", "--seconds", "0.1", "--json"],
])
def test_motor_params_reach_the_simulated_robot(monkeypatch, tmp_path, command):
    """A fitted params.json given on the command line is in the simulated robot's model and actuator model."""
    from toddlerbot.sim import mujoco_robot

    robots = []
    original_init = mujoco_robot.MuJoCoRobot.__init__

    def recording_init(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        robots.append(self)

    monkeypatch.setattr(mujoco_robot.MuJoCoRobot, "__init__", recording_init)
    params = tmp_path / "xm430.json"
    params.write_text('{"motor": "XM430", "actuator": {"armature": 0.0031, "tau_max": 1.23}}')
    result = CliRunner().invoke(app, [*command, "--motor-params", str(params)])
    assert result.exit_code == 0, result.output
    (robot,) = robots
    knee = robot.motor_names.index("left_knee_drive")
    assert robot.model.dof_armature[robot.model.joint("left_knee_drive").dofadr[0]] == pytest.approx(0.0031)
    assert robot.description.actuator_params[knee].tau_max == pytest.approx(1.23)
    assert robot.description.motor_params_files == (str(params),)


def test_model_info_and_build_use_the_fitted_motor_params(tmp_path):
    params = tmp_path / "xm430.json"
    params.write_text('{"motor": "XM430", "actuator": {"armature": 0.0031, "tau_max": 1.23}}')
    info = CliRunner().invoke(app, ["model", "info", "--json", "--motor-params", str(params)])
    assert info.exit_code == 0, info.output
    rows = json.loads(info.output)["motors"]
    fitted = [r["tau_max"] for r in rows if r["model"] == "XM430-W210"]
    assert fitted == pytest.approx([1.23] * 4)  # knees and ankle pitch
    assert all(r["tau_max"] != pytest.approx(1.23) for r in rows if r["model"] != "XM430-W210")
    xml = tmp_path / "robot.xml"
    built = CliRunner().invoke(app, ["model", "build", "-o", str(xml), "--motor-params", str(params)])
    assert built.exit_code == 0, built.output
    model = mujoco.MjModel.from_xml_path(str(xml))
    assert model.dof_armature[model.joint("left_knee_drive").dofadr[0]] == pytest.approx(0.0031)


HELP_PROBE = """
import toddlerbot.robot.spec as spec_module
calls = []
original = spec_module._validate
spec_module._validate = lambda *a: calls.append(a) or original(*a)
from typer.testing import CliRunner
from toddlerbot.cli.main import app
codes = [CliRunner().invoke(app, args).exit_code for args in (["--help"], *[[a, "--help"] for a in {areas!r}])]
print(codes, len(calls))
"""


def test_cli_help_parses_no_spec():
    areas = ["model", "design", "sim", "actuator", "sysid", "hw", "rl", "eval"]
    proc = subprocess.run([sys.executable, "-c", HELP_PROBE.format(areas=areas)], capture_output=True, text=True,
                          timeout=120, check=True)
    codes, calls = proc.stdout.strip().rsplit(" ", 1)
    assert json.loads(codes) == [0] * (len(areas) + 1)
    assert int(calls) == 0
