import json

import pytest
from typer.testing import CliRunner

from toddlerbot.cli.main import app
from toddlerbot.design.budget import PowerInputs, power_budget, weight_estimate
from toddlerbot.design.power_factor import power_factor_of, reference_humanoids, robot_power_factor
from toddlerbot.design.range_of_motion import range_of_motion
from toddlerbot.design.report import design_report
from toddlerbot.design.torque_requirement import check_joints, required_torques

runner = CliRunner()


def test_eq5_reproduces_the_appendix_torques():
    tau = required_torques(height_m=0.5, mass_kg=3.1)
    assert round(tau["knee"], 2) == 2.35
    assert round(tau["ankle_pitch"], 2) == 2.66
    assert round(tau["hip_pitch"], 2) == 1.77


def test_power_factor_from_stall_torques(description):
    pf = robot_power_factor(description, height_m=0.56, mass_kg=3.4)
    assert pf.sum_torque_nm == pytest.approx(50.8)  # Table 2 x motor assignment
    assert pf.total == pytest.approx(50.8 / (0.56 * 3.4 * 9.81))
    assert pf.upper + pf.lower == pytest.approx(pf.total)
    assert pf.lower == pytest.approx(25.0 / (0.56 * 3.4 * 9.81))  # legs: 2 XC330 + 4 2XC430 + 4 XM430 + 2 XC430


def test_reference_humanoids_have_sources_and_plausible_power_factors():
    robots = {h.name: h for h in reference_humanoids()}
    op3 = robots["ROBOTIS OP3"]
    assert op3.power_factor == pytest.approx(82.0 / (0.51 * 3.5 * 9.81))
    assert all(h.source for h in robots.values())
    assert all(0.5 < h.power_factor < 6 for h in robots.values())


def test_joints_below_requirement_are_flagged(description):
    at_design_size = check_joints(description, 0.5, 3.1)
    assert all(c.sufficient for c in at_design_size)  # XM430 3.0 >= 2.66, 2XC430 1.8 >= 1.77
    heavier = {c.joint: c for c in check_joints(description, 0.5, 3.5)}
    assert not heavier["left_hip_pitch"].sufficient and not heavier["right_hip_pitch"].sufficient
    assert heavier["left_knee"].sufficient
    assert heavier["left_knee"].available_nm == pytest.approx(3.0)


def test_weight_estimate_and_power_budget(description):
    weight = weight_estimate(description)
    assert weight.estimate_kg == pytest.approx(3.1)  # appendix: 30 x 50 g + 600 g + 1000 g
    assert weight.error_fraction == pytest.approx((3.1 - 3.358) / 3.358, abs=0.01)
    budget = power_budget(PowerInputs())
    assert budget.motors_w == pytest.approx(50.4)  # appendix: about 50 W at 70 % duty
    assert budget.battery_wh_for_target == pytest.approx(76.9, abs=0.1)  # appendix: 75 Wh for one hour
    assert budget.peak_power_w == pytest.approx(370.0)  # 14.8 V x 25 A
    assert power_budget(PowerInputs(battery_capacity_ah=2.0)).runtime_h == pytest.approx(29.6 * 0.85 / 65.4)
    with pytest.raises(ValueError, match="duty_cycle"):
        PowerInputs(duty_cycle=1.5)


def test_range_of_motion_compares_every_joint_with_human_values(description):
    rows = {r.joint: r for r in range_of_motion(description)}
    assert rows["left_knee"].robot_span_deg == pytest.approx(120.0, abs=0.01)
    assert rows["left_knee"].human_joint == "knee_pitch"
    assert rows["left_knee"].human_span_deg == pytest.approx(130.0)
    assert len(rows) == 17  # 4 midline joints + 13 left-side joints


def test_design_report_json_from_cli():
    result = runner.invoke(app, ["design", "report", "--json", "--height", "0.5", "--mass", "3.1"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["height_m"] == 0.5 and data["mass_kg"] == 3.1
    assert {k: round(v, 2) for k, v in data["torque_requirement_nm"].items()} == {
        "knee": 2.35, "ankle_pitch": 2.66, "hip_pitch": 1.77}
    pf = data["power_factor"]
    assert pf["total"] == pytest.approx(pf["upper"] + pf["lower"])
    assert pf["total"] == pytest.approx(power_factor_of(50.8, 0.5, 3.1))


def test_design_report_defaults_to_the_models_size(spec, description):
    result = runner.invoke(app, ["design", "report", "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["insufficient_joints"] == [
        "left_ankle_pitch", "right_ankle_pitch", "left_hip_pitch", "right_hip_pitch"]
    report = design_report(description)
    assert report.height_m == pytest.approx(0.553, abs=0.005)
    assert report.mass_kg == pytest.approx(3.358, rel=0.001)
    assert {c.joint for c in report.insufficient_joints} == {
        "left_ankle_pitch", "right_ankle_pitch", "left_hip_pitch", "right_hip_pitch"}


def test_design_plots_are_written(tmp_path):
    result = runner.invoke(app, ["design", "report", "--plot", str(tmp_path)])
    assert result.exit_code == 0, result.output
    for name in ("power_factor", "range_of_motion", "torque_requirement"):
        png = (tmp_path / f"{name}.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_negative_height_is_refused():
    result = runner.invoke(app, ["design", "report", "--height", "-1"])
    assert result.exit_code == 2
    assert "must be positive" in result.output
