import json

import numpy as np
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


TAB_RED, TAB_ORANGE = (214, 39, 40), (255, 127, 14)


def _bars(image: np.ndarray, rgb: tuple[int, int, int], axis: int) -> int:
    """Separate bars of one colour across an RGB image: runs of columns (axis 0) or rows (axis 1) holding it."""
    holds = (np.abs(image - np.array(rgb)).max(axis=2) < 40).sum(axis=axis) > 5
    return int(np.sum(np.diff(np.concatenate([[0], holds.astype(int), [0]])) == 1))


def test_design_plots_show_the_report(tmp_path, description):
    from PIL import Image

    result = runner.invoke(app, ["design", "report", "--plot", str(tmp_path)])
    assert result.exit_code == 0, result.output
    report = design_report(description)
    images = {name: np.asarray(Image.open(tmp_path / f"{name}.png").convert("RGB")).astype(int)
              for name in ("power_factor", "range_of_motion", "torque_requirement")}
    rows = len(report.range_of_motion)
    # the figure sizes at 120 dpi: 7 x 4.5 in, 7 x (0.35 per joint + 1.5) in, 7 x 3.5 in
    assert images["power_factor"].shape == (540, 840, 3)
    assert images["range_of_motion"].shape == (round((0.35 * rows + 1.5) * 120), 840, 3)
    assert images["torque_requirement"].shape == (420, 840, 3)
    # one red bar per joint whose stall torque is below Eq. 5's requirement (4 at the model's size)
    assert _bars(images["torque_requirement"], TAB_RED, axis=0) == len(report.insufficient_joints) == 4
    # one orange ToddlerBot bar per joint in the range-of-motion chart, plus its legend patch
    assert _bars(images["range_of_motion"], TAB_ORANGE, axis=1) == rows + 1
    # the power-factor chart is drawn (measured: 4.8 % of its pixels are not white)
    assert (images["power_factor"].min(axis=2) < 200).mean() > 0.02


def test_negative_height_is_refused():
    result = runner.invoke(app, ["design", "report", "--height", "-1"])
    assert str(result.exception) == "--height -1: expected a number of m in [0.1, 2.5]"
