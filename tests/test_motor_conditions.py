"""The robot's motors under each motor model and moved by the XL330 fits' standard errors
(`toddlerbot.sim.motor_conditions`, docs/sysid.md "Walking under each motor model")."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from toddlerbot.actuation.dc_motor import DCMotorParams
from toddlerbot.actuation.params_file import relative_errors
from toddlerbot.errors import ParamsError, ToddlerbotError
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.tracking import TRACKING_BARS, evaluate_policy
from toddlerbot.sim.motor_conditions import ReferenceFit, motor_conditions, reference_fits, under_model

FITS = Path(__file__).parents[1] / "benchmarks" / "results" / "xl330_fits"
XC330 = "XC330-T288"


@pytest.fixture(scope="module")
def robot() -> RobotDescription:
    return RobotDescription.load()


@pytest.fixture(scope="module")
def conditions(robot) -> dict[str, RobotDescription]:
    return motor_conditions(robot, reference_fits(FITS))


def _xc330(conditions, name):
    return conditions[name].catalogue[XC330].actuator


def test_relative_errors_are_read_from_a_fit(tmp_path):
    errors = relative_errors(FITS / "dc_motor.json")
    assert errors["stall_torque"] == pytest.approx(0.0221, abs=1e-4)
    assert errors["frictionloss"] == pytest.approx(0.0733, abs=1e-4)
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps({"motor": "XC330", "actuator": {"damping": 0.004}}))
    assert relative_errors(plain) == {}
    plain.write_text(json.dumps({"motor": "XC330", "actuator": {}, "fit": {"uncertainty": {"damping": 0.1}}}))
    with pytest.raises(ParamsError, match=r"fit\.uncertainty"):
        relative_errors(plain)


def test_every_model_as_it_is_moved_and_with_load_friction(conditions):
    assert list(conditions) == [
        "appendix", "appendix weaker", "appendix stronger",
        "extended", "extended weaker", "extended stronger", "extended + load friction",
        "dc_motor", "dc_motor weaker", "dc_motor stronger", "dc_motor + load friction"]


def test_the_appendix_condition_is_the_catalogue(robot, conditions):
    for motor in {m.model for m in robot.motors}:
        assert conditions["appendix"].catalogue[motor].actuator == robot.catalogue[motor].actuator


def test_other_models_keep_table_3_and_take_the_rest_from_the_reference(robot, conditions):
    table3 = robot.catalogue[XC330].actuator
    dc = _xc330(conditions, "dc_motor")
    assert dc == DCMotorParams.like(table3).replace(pwm_exponent=dc.pwm_exponent)
    assert dc.pwm_exponent == pytest.approx(0.8042, abs=1e-4)
    assert dc.stall_torque == table3.tau_max and dc.load_friction == 0.0
    assert _xc330(conditions, "dc_motor + load friction").load_friction == pytest.approx(0.4216, abs=1e-4)
    extended = _xc330(conditions, "extended")
    # stiction by the datasheet stall torques: 0.0050 N m on the XL330 (0.52 N m) -> the XC330 (1.0 N m)
    assert extended.stiction == pytest.approx(0.004998 * 1.0 / 0.52, rel=1e-3)
    assert extended.replace(stiction=0.0, stribeck_velocity=0.1) == table3
    assert _xc330(conditions, "extended + load friction").load_friction == pytest.approx(0.5246, abs=1e-4)


def test_moves_go_by_the_identified_standard_errors_toward_a_weaker_or_stronger_motor(conditions):
    dc, weaker, stronger = (_xc330(conditions, f"dc_motor {m}".strip()) for m in ("", "weaker", "stronger"))
    assert weaker.stall_torque == pytest.approx(dc.stall_torque * (1 - 0.0221), rel=1e-3)
    assert weaker.damping == pytest.approx(dc.damping * (1 + 0.0406), rel=1e-3)
    assert stronger.no_load_speed == pytest.approx(dc.no_load_speed * (1 + 0.0261), rel=1e-3)
    assert stronger.pwm_per_rad == dc.pwm_per_rad  # fixed in the fit: no standard error
    extended, weaker = _xc330(conditions, "extended"), _xc330(conditions, "extended weaker")
    assert weaker.tau_max == pytest.approx(extended.tau_max * (1 - 0.125), rel=1e-3)
    assert weaker.kp_scale == pytest.approx(extended.kp_scale * (1 + 0.0286), rel=1e-3)  # a softer gain
    # not identified by the logs (relative error 97 % and 5,279 x): left as they are
    assert (weaker.frictionloss, weaker.tau_brake) == (extended.frictionloss, extended.tau_brake)


def test_a_condition_starts_from_the_appendix_model():
    reference = ReferenceFit.load(FITS / "dc_motor.json")
    with pytest.raises(ToddlerbotError, match="starts from the appendix model"):
        under_model(reference.params, 0.52, reference)


@pytest.mark.slow
def test_both_walkers_walk_the_schedule_with_the_robots_motors_as_dc_motors(conditions):
    """The catalogue's motors as DC motors (back-EMF instead of Eq. 9's line, no kd_min, the XL330's PWM shape):
    neither walker falls over Table 7's 26 s schedule and both track the velocities within 1.5 x Table 7, but
    walk-rl's position error doubles (0.134 m against 0.063 under the appendix model; walk-zmp 0.060 and 0.060;
    docs/sysid.md "Walking under each motor model", measured with walk-rl stepping in place at the schedule's zero
    commands, as here)."""
    for policy in ("walk-rl", "walk-zmp"):
        result = evaluate_policy(conditions["dc_motor"], policy, **({"stand": False} if policy == "walk-rl" else {}))
        assert result.falls == 0, policy
        assert result.lin_vel_mps < TRACKING_BARS[1] and result.ang_vel_radps < TRACKING_BARS[2], policy
        position = (0.1, 0.2) if policy == "walk-rl" else (0.0, TRACKING_BARS[0])
        assert position[0] < result.position_m < position[1], policy
