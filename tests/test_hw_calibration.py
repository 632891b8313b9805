"""Zero-point calibration against the emulator, calibration files, and the real-robot backend applying them."""

import numpy as np
import pytest
from typer.testing import CliRunner

from hw_support import emulated
from toddlerbot.cli.hw import app
from toddlerbot.hardware.calibration import (
    GROUPS,
    Calibration,
    CalibrationError,
    group_motors,
    load_calibration,
    measure_offsets,
    merge,
    save_calibration,
)
from toddlerbot.hardware.control_table import RAD_PER_PULSE
from toddlerbot.hardware.driver import DynamixelBus, motors_of
from toddlerbot.hardware.real_robot import RealRobot, StartupCheckError
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.safety import SLEW_SPEEDS
from toddlerbot.robot.spec import load_spec

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

SPEC = load_spec()
DESC = RobotDescription(SPEC)


def _calibrate(path, group, existing=None, robot="tb-07", spec=SPEC, force=False):
    ids = {m.id for m in group_motors(RobotDescription(spec), group)}
    with DynamixelBus(path, motors_of(RobotDescription(spec), ids)) as bus:
        return merge(existing, robot, RobotDescription(spec), group, measure_offsets(bus), force=force)


def test_groups_follow_the_jigs_and_cover_every_motor():
    sizes = {g: len(group_motors(DESC, g)) for g in GROUPS}
    assert sizes == {"arm": 14, "neck": 2, "hip": 8, "ankle": 6}
    assert {m.joint for m in group_motors(DESC, "ankle")} == {
        "left_knee_drive", "left_ankle_roll", "left_ankle_pitch", "right_knee_drive", "right_ankle_roll",
        "right_ankle_pitch"}
    gripper = SPEC.with_variant("gripper")
    assert len(group_motors(RobotDescription(gripper), "arm")) == 16


def test_group_by_group_calibration_recovers_the_hidden_offsets(tmp_path):
    with emulated(SPEC, offsets_seed=5) as (emu, path):
        cal = None
        for group in GROUPS:
            cal = _calibrate(path, group, cal)
        assert not any(m.torque_on for m in emu.motors)
    assert cal.offsets == {m.name: m.mounting_offset for m in emu.motors}
    assert set(cal.groups) == set(GROUPS)
    save_calibration(cal, tmp_path / "tb-07.yaml")
    loaded = load_calibration(tmp_path / "tb-07.yaml", DESC, robot="tb-07")
    assert loaded.offsets == cal.offsets


def test_cli_calibrates_one_group_and_refuses_to_overwrite_with_implausible_values(tmp_path):
    out = tmp_path / "tb-07.yaml"
    runner = CliRunner()
    cli = ["calibrate", "-o", str(out), "--robot", "tb-07", "--group", "neck"]
    with emulated(SPEC, offsets_seed=1) as (emu, path):
        result = runner.invoke(app, [*cli, "--port", path])
        assert result.exit_code == 0, result.output
        assert load_calibration(out).offsets == {m.name: m.mounting_offset for m in emu.motors[:2]}
    good = out.read_bytes()
    with emulated(SPEC, offsets_seed=2) as (emu, path):  # same robot "rebuilt": the neck offsets jump
        result = runner.invoke(app, [*cli, "--port", path])
        assert isinstance(result.exception, CalibrationError)
        assert "refusing to overwrite good offsets" in str(result.exception)
        assert "neck_yaw_drive moved" in str(result.exception)
        assert out.read_bytes() == good  # nothing written
        result = runner.invoke(app, [*cli, "--port", path, "--force"])
        assert result.exit_code == 0
        assert load_calibration(out).offsets["neck_yaw_drive"] == emu.motors[0].mounting_offset


def test_a_moving_joint_is_implausible(tmp_path):
    with emulated(SPEC) as (emu, path):
        emu.plant.qd[0] = 6.0  # neck yaw swinging: its jig is not in place
        with pytest.raises(CalibrationError, match=r"motor 0 \(neck_yaw_drive, XC330-T288\) is moving"):
            _calibrate(path, "neck")


def test_calibration_for_another_robot_or_spec_is_refused(tmp_path):
    cal = Calibration("tb-07", "toddlerbot_v1", {m.joint: 2048 for m in SPEC.motors})
    path = tmp_path / "tb-07.yaml"
    save_calibration(cal, path)
    with pytest.raises(CalibrationError, match=rf"{path}: calibration of robot 'tb-07', not of 'tb-08'"):
        load_calibration(path, DESC, robot="tb-08")
    with pytest.raises(CalibrationError, match=rf"{path}: made for spec 'toddlerbot_v1'.*toddlerbot_v1\+gripper"):
        load_calibration(path, RobotDescription(SPEC.with_variant("gripper")))
    with pytest.raises(CalibrationError, match="belongs to robot 'tb-07'"):
        merge(cal, "tb-08", DESC, "neck", {"neck_yaw_drive": 1})
    partial = Calibration("tb-07", "toddlerbot_v1", {"neck_yaw_drive": 1})
    with pytest.raises(CalibrationError, match=r"no zero offset for neck_pitch_drive.*ankle, arm, hip, neck"):
        partial.offsets_for(DESC)
    with pytest.raises(CalibrationError, match="cannot read calibration file"):
        load_calibration(tmp_path / "missing.yaml")


def test_real_robot_applies_offsets_and_recovers_multi_turn_positions():
    with emulated(SPEC, offsets_seed=9) as (emu, path):
        cal = Calibration("tb", "toddlerbot_v1", {m.name: m.mounting_offset for m in emu.motors})
        # power up with the neck yaw at +2.5 rad and the left hip pitch at -1.2 rad: readings wrap into 0..4095
        emu.plant.q[0], emu.plant.q[4] = 2.5, -1.2
        with emu.lock:
            for m in emu.motors:
                emu._power_up(m)
        assert all(0 <= m.get("present_position") < 4096 for m in emu.motors)
        with RealRobot(DESC, path, cal, control_dt=0.01) as robot:
            robot.bus.open()
            robot.bus.scan()
            state = robot.bus.read_state()
            robot.resolve_turns(state.position)
            q = robot._angles(state.position)
            assert q[0] == pytest.approx(2.5, abs=2 * RAD_PER_PULSE)
            assert q[4] == pytest.approx(-1.2, abs=2 * RAD_PER_PULSE)
            assert np.abs(q - emu.plant.q).max() < 2 * RAD_PER_PULSE


def test_real_robot_reset_reaches_home_and_step_writes_new_gains():
    with emulated(SPEC, offsets_seed=4) as (emu, path):
        cal = Calibration("tb", "toddlerbot_v1", {m.name: m.mounting_offset for m in emu.motors})
        with RealRobot(DESC, path, cal, control_dt=0.01, reset_duration=0.3) as robot:
            obs = robot.reset()
            home = robot.description.home_motor_pos
            for _ in range(30):
                obs = robot.step(home)
            assert np.abs(obs.motor_pos - home).max() < 0.05
            assert obs.joint_pos == pytest.approx(robot.transmission.motor_to_joint(obs.motor_pos))
            kp = robot.default_kp * 0.5
            robot.step(home, kp=kp, kd=np.full(30, 7))
            assert [m.get("position_p_gain") for m in emu.motors] == [int(k) for k in kp]
            assert {m.get("position_d_gain") for m in emu.motors} == {7}
            wild = home.copy()
            wild[0] = 10.0  # beyond neck yaw's joint range: slew-limited, then clipped to the range
            step = robot.guard.max_step[0]
            assert step == pytest.approx(SLEW_SPEEDS * 6.5 * 0.01)  # XC330 no-load speed x control period
            goals = []
            for _ in range(80):
                robot.step(wild)
                goals.append(robot._angles(np.array([emu.motor(0).get("goal_position")]))[0])
            assert goals[0] == pytest.approx(home[0] + step, abs=RAD_PER_PULSE)
            assert np.diff(goals).max() <= step + RAD_PER_PULSE
            assert goals[-1] == pytest.approx(robot.upper[0], abs=RAD_PER_PULSE)
        assert not any(m.torque_on for m in emu.motors)


_GOOD = {m.joint: 2048 for m in SPEC.motors}


@pytest.mark.parametrize(("text", "expected"), [
    (b"", "expected a mapping with 'robot', 'spec' and 'offsets'"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: {neck_yaw_drive: 2", "not valid YAML"),
    (b"\xff\xfe\x00binary", "not UTF-8 text"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: [1, 2]\n", "'offsets' must map motor names"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: {neck_yaw_drive: true}\n", r"offsets.neck_yaw_drive is True"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: {neck_yaw_drive: 100.0}\n", r"offsets.neck_yaw_drive is 100.0"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: {neck_yaw_drive: -5}\n", r"is -5; expected .* in 0..4095"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: {neck_yaw_drive: 5644}\n", r"is 5644; expected .* in 0..4095"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: {neck_yaw_drive: .nan}\n", r"is nan"),
    (b"robot: tb\nspec: toddlerbot_v1\noffsets: {}\ngroups: {neck: [1]}\n", "'groups' must map"),
    (b"a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
     b"c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\nrobot: *c\n", "expected a mapping with 'robot'"),
])
def test_hostile_calibration_files_get_one_line_errors(tmp_path, text, expected):
    path = tmp_path / "cal.yaml"
    path.write_bytes(text)
    with pytest.raises(CalibrationError, match=expected) as info:
        load_calibration(path, DESC)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


def test_oversized_calibration_file_is_refused_before_parsing(tmp_path):
    path = tmp_path / "huge.yaml"
    path.write_bytes(b"#" * 2_000_001)
    with pytest.raises(CalibrationError, match=r"2000001 bytes is too large for a calibration file \(at most 1000000"):
        load_calibration(path)


def test_unknown_motor_in_calibration_is_refused(tmp_path):
    path = tmp_path / "cal.yaml"
    save_calibration(Calibration("tb", "toddlerbot_v1", {**_GOOD, "tail_wag": 3}), path)
    with pytest.raises(CalibrationError, match="unknown motor 'tail_wag'"):
        load_calibration(path, DESC)
    assert load_calibration(tmp_path / "cal.yaml").offsets["tail_wag"] == 3  # without a robot: just the file


def test_start_up_check_refuses_an_offset_that_puts_a_joint_past_its_range():
    """+1500 pulses on the left ankle pitch (about +2.3 rad) is caught while the motors are limp: torque never
    comes on and the error names the motor and the file."""
    with emulated(SPEC, offsets_seed=3) as (emu, path):
        offsets = {m.name: m.mounting_offset for m in emu.motors}
        offsets["left_ankle_pitch"] = (offsets["left_ankle_pitch"] - 1500) % 4096
        robot = RealRobot(DESC, path, Calibration("tb", "toddlerbot_v1", offsets), calibration_source="tb.yaml")
        with pytest.raises(StartupCheckError, match=r"left_ankle_pitch reads \+2\.\d\d rad, range \[-1\.75, \+0\.79\]"
                           r".*check tb.yaml"), robot:
            robot.reset()
        assert not any(m.torque_on for m in emu.motors)
        assert emu.stats.by_instruction.get(0x03, 0) > 0  # configured (writes) but never enabled
