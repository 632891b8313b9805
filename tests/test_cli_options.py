"""CLI options that typer accepts but no run can use (NaN, inf, <= 0, unwritable outputs, empty weights) are
refused with one line before anything starts: no bus is opened, no simulation is built."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from toddlerbot.cli import hw, sim
from toddlerbot.cli.options import RobotOptions
from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware.calibration import Calibration, save_calibration
from toddlerbot.robot.description import RobotDescription

NO_PORT = "/dev/ttyNOPE"  # reaching the bus would fail differently ("cannot open serial port")


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    path = tmp_path_factory.mktemp("cal") / "cal.yaml"
    save_calibration(Calibration("tb", "toddlerbot_v1", {n: 2048 for n in RobotDescription.load().motor_names}),
                     path)
    return path


def _error(app, args: list[str]) -> str:
    result = CliRunner().invoke(app, args)
    assert isinstance(result.exception, ToddlerbotError), result.output
    message = str(result.exception)
    assert "\n" not in message and "cannot open serial port" not in message
    return message


@pytest.mark.parametrize(("option", "value", "expected"), [
    ("--seconds", "nan", "--seconds nan: expected a duration in (0, 3600] seconds"),
    ("--seconds", "inf", "--seconds inf: expected a duration in (0, 3600] seconds"),
    ("--seconds", "0", "--seconds 0: expected"),
    ("--seconds", "-1", "--seconds -1: expected"),
    ("--seconds", "1e300", "--seconds 1e+300: expected a duration in (0, 3600] seconds"),
    ("--dt", "nan", "--dt nan: expected a duration in (0, 0.1] seconds"),
    ("--dt", "1e400", "--dt inf: expected"),
    ("--dt", "5", "--dt 5: expected a duration in (0, 0.1] seconds"),
    ("--control-hz", "nan", "--control-hz nan: expected a number of Hz in [10, 1000]"),
    ("--control-hz", "5", "--control-hz 5: expected a number of Hz in [10, 1000]"),  # the Bus Watchdog's 0.1 s
    ("--control-hz", "1e9", "--control-hz 1e+09: expected a number of Hz in [10, 1000]"),
    ("--latency-ms", "0", "--latency-ms 0: expected a duration in (0, 1000] milliseconds"),
    ("--latency-ms", "5000", "--latency-ms 5000: expected a duration in (0, 1000] milliseconds"),
])
def test_hw_run_refuses_unusable_numbers(calibration, option, value, expected):
    assert expected in _error(hw.app, ["run", "--port", NO_PORT, "--calibration", str(calibration), option, value])


@pytest.mark.parametrize(("option", "value", "expected"), [
    ("--seconds", "nan", "--seconds nan: expected"),
    ("--control-hz", "nan", "--control-hz nan: expected a finite number of Hz > 0"),
    ("--control-hz", "inf", "--control-hz inf: expected"),
    ("--control-hz", "-50", "--control-hz -50.0: expected"),
])
def test_sim_run_refuses_unusable_numbers(option, value, expected):
    assert expected in _error(sim.app, ["run", "--policy", "stand", option, value])


def test_unwritable_log_is_reported_before_the_run(calibration, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    log = blocker / "run.npz"
    message = _error(hw.app, ["run", "--port", NO_PORT, "--calibration", str(calibration), "--log", str(log)])
    assert f"--log {log}: cannot write there" in message
    message = _error(sim.app, ["run", "--policy", "stand", "--log", str(tmp_path)])
    assert f"--log {tmp_path}: is a directory" in message


def test_empty_weights_file_is_one_line_before_the_bus(calibration, tmp_path):
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    message = _error(hw.app, ["run", "--port", NO_PORT, "--calibration", str(calibration), "--policy", "walk-rl",
                              "--weights", str(empty)])
    assert message == f"{empty}: empty file, not an exported RL policy"


def test_robot_options_build_the_variants_description_and_base(tmp_path):
    params = tmp_path / "xc330.json"
    params.write_text('{"motor": "XC330", "actuator": {"armature": 0.0123}}')
    plain, plain_base = RobotOptions().load()
    gripper, gripper_base = RobotOptions.of(variant="gripper", motor_params=[params]).load()
    assert (plain.n_motors, plain_base, plain.motor_params_files) == (30, "floating", ())
    assert (gripper.n_motors, gripper_base, gripper.spec.variant) == (32, "floating", "gripper")
    assert gripper.motor_params_files == (str(params),) and gripper.catalogue["XC330"].actuator.armature == 0.0123
    assert RobotOptions.of(variant="fixed").load()[1] == "fixed"


def test_model_base_overrides_the_variants_and_unknown_variant_is_named():
    from toddlerbot.cli import model

    result = CliRunner().invoke(model.app, ["info", "--variant", "gripper", "--base", "fixed", "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    assert info["actuators"] == 32 and info["nq"] == info["nv"]  # the gripper's motors, no free joint
    floating = json.loads(CliRunner().invoke(model.app, ["info", "--json"]).output)
    assert floating["nq"] == floating["nv"] + 1  # the free joint: a quaternion (4) for 3 angular velocities
    unknown = CliRunner().invoke(model.app, ["info", "--variant", "wings"])
    assert unknown.exit_code == 2 and "'wings' is not one of floating, fixed, gripper" in unknown.output


@pytest.mark.parametrize("option", ["--asymmetric", "--step-in-place"])  # stand has no mirror and no stance
@pytest.mark.parametrize("app,args", [
    (sim.app, ["run", "--policy", "stand"]),
    (hw.app, ["run", "--port", NO_PORT, "--policy", "stand"]),
])
def test_a_walk_rl_option_is_refused_for_a_policy_without_it(calibration, app, args, option):
    if app is hw.app:
        args = [*args, "--calibration", str(calibration)]
    assert _error(app, [*args, option]) == f"{option} is not an option of policy 'stand'"


def _tracking_with_and_without(commands: str, option: str) -> dict[bool, dict]:
    """`eval tracking --json` of walk-rl for 3 s of ``commands``, without (False) and with (True) ``option``."""
    from toddlerbot.cli import eval as eval_cli

    args = ["--policy", "walk-rl", "--commands", commands, "--seconds", "3", "--json"]
    runs = {}
    for extra in ([], [option]):
        result = CliRunner().invoke(eval_cli.app, [*args, *extra])
        assert result.exit_code == 0, result.output
        runs[bool(extra)] = json.loads(result.output)
    return runs


def test_eval_tracking_step_in_place_steps_where_walk_rl_stands():
    """At a zero command walk-rl stands still by default and steps in place with `--step-in-place`."""
    runs = _tracking_with_and_without("0:0,0,0", "--step-in-place")
    assert runs[False]["position_m"] < 0.01 < runs[True]["position_m"]  # 0.004 and 0.030 m


def test_eval_tracking_asymmetric_runs_walk_rl_alone():
    """The symmetric default and `--asymmetric` walk differently, and `--asymmetric` is the policy alone."""
    from toddlerbot.runtime.tracking import evaluate_policy

    runs = _tracking_with_and_without("0:0,0.05,0", "--asymmetric")
    alone = evaluate_policy(RobotDescription.load(), "walk-rl", "0:0,0.05,0", 3.0, symmetric=False).summary()
    assert runs[True]["position_m"] == pytest.approx(alone["position_m"], abs=1e-9)
    assert abs(runs[True]["position_m"] - runs[False]["position_m"]) > 1e-4


def test_hw_run_takes_the_rate_in_hz_and_dt_as_a_deprecated_alias(calibration):
    """One spelling of the control rate across commands (`--control-hz`, as `sim run`); `--dt` still works, says it
    is deprecated and what to write instead, and may not be given with `--control-hz`."""
    args = ["run", "--port", NO_PORT, "--calibration", str(calibration), "--imu", "none"]
    result = CliRunner().invoke(hw.app, [*args, "--dt", "0.025"])
    assert "warning: --dt is deprecated; use --control-hz 40" in " ".join(result.output.split())
    assert "cannot open serial port" in str(result.exception)  # then it goes on, at 40 Hz, to the bus
    assert _error(hw.app, [*args, "--dt", "0.02", "--control-hz", "50"]) == (
        "--dt and --control-hz both give the control rate; keep --control-hz")
    result = CliRunner().invoke(hw.app, [*args, "--control-hz", "25"])
    assert "cannot open serial port" in str(result.exception) and "deprecated" not in result.output
