"""`eval tracking --log`: Table 7's errors of a logged run, from the log's ground truth or from a motion-capture CSV
aligned on the IMU gyro. Synthetic logs for the alignment and every refusal (milliseconds); a short walk in
hardware-in-the-loop for the agreement with what `hw run` reported and for a capture made from that walk."""

import json
import re
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from toddlerbot.locomotion.config import WalkConfig
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.mocap import IMU_AGE_S, log_tracking, read_capture

OFFSET_S = 0.37
MOCAP_HZ = 120.0
DT = 0.02


def _synthetic_log(seconds: float = 12.0, imu_age_s: float = IMU_AGE_S, turns: bool = True,
                   regular: bool = False) -> RunLog:
    """A walk as a log holds it: forward, a turn and a curve (`turns`; else straight on), with the gait's yaw, roll
    and pitch sway, whose period and amplitude wander by 10 and 30 % as a real gait's do (`regular`: not at all);
    the IMU reads the torso `imu_age_s` late, as the BNO08x does. No motors."""
    fine = np.arange(-1.0, seconds + 1.0, 0.001)
    yaw_rate = np.select([fine < 4, fine < 8], [0.0, 0.3], 0.2) * turns
    wander = np.interp(fine, np.arange(-1.0, seconds + 2.0), np.random.default_rng(7).uniform(-1, 1, int(seconds) + 3))
    wander *= not regular
    phase = np.cumsum(2 * np.pi / WalkConfig.cycle_time * (1 + 0.1 * wander)) * 0.001
    yaw = np.cumsum(yaw_rate) * 0.001 + 0.05 * (1 + 0.3 * wander) * np.sin(phase)
    sway = 0.03 * np.sin(phase + 0.4)
    rotation = Rotation.from_euler("ZYX", np.column_stack([yaw, 0.5 * sway, sway]))
    body_rate = (rotation[:-1].inv() * rotation[1:]).as_rotvec() / 0.001  # body-frame angular velocity
    time = np.arange(0.0, seconds, DT)
    at = np.searchsorted(fine, time)
    late = np.searchsorted(fine, time - imu_age_s)
    speed = np.where(fine >= 1, 0.1, 0.0)
    xy = np.cumsum(np.column_stack([np.cos(yaw), np.sin(yaw)]) * speed[:, None] * 0.001, axis=0)
    command = np.column_stack([np.where(time >= 1, 0.1, 0.0), np.zeros_like(time), yaw_rate[at]])
    n = len(time)
    zeros = np.zeros((n, 1))
    return RunLog(
        time=time, command=command, motor_pos=zeros, motor_vel=zeros, motor_torque=zeros, joint_pos=zeros,
        joint_vel=zeros, motor_target=zeros, joint_target=zeros,
        imu_quat=rotation[late].as_quat(scalar_first=True), imu_ang_vel=body_rate[late],
        imu_lin_acc=np.tile([0.0, 0.0, 9.81], (n, 1)), foot_contact=np.zeros((n, 2)),
        base_pos=np.column_stack([xy[at], np.full(n, 0.3)]), base_quat=rotation[at].as_quat(scalar_first=True),
        compute_time=np.zeros(n), step_period=np.full(n, DT), motor_names=("m",), joint_names=("j",),
        control_dt=DT, policy="walk-rl")


def write_capture(log: RunLog, path, offset_s: float = OFFSET_S, rate_hz: float = MOCAP_HZ, seed: int = 0,
                  pad_s: float = 2.0, conjugate: bool = False) -> None:
    """A motion capture of the log's ground truth as `eval tracking --mocap` reads it: on a clock `offset_s` ahead
    of the log's, at `rate_hz`, with 0.5 mm and 0.1 deg of noise (an optical system's), the robot standing still
    for `pad_s` before and after the run. `conjugate`: the quaternions inverted (an export of the world in the body's
    frame)."""
    rng = np.random.default_rng(seed)
    t = np.arange(log.time[0] - pad_s, log.time[-1] + pad_s, 1 / rate_hz) + offset_s
    at = np.clip(t - offset_s, log.time[0], log.time[-1])
    pos = np.stack([np.interp(at, log.time, log.base_pos[:, k]) for k in range(3)], axis=1)
    pos += rng.normal(0, 0.0005, pos.shape)
    rot = Slerp(log.time, Rotation.from_quat(log.base_quat, scalar_first=True))(at)
    quat = (Rotation.from_rotvec(rng.normal(0, np.radians(0.1), (len(t), 3))) * rot).as_quat(scalar_first=True)
    quat[:, 1:] *= -1 if conjugate else 1
    rows = "\n".join(",".join(f"{v:.6f}" for v in row) for row in np.column_stack([t, pos, quat]))
    path.write_text("time,x,y,z,qw,qx,qy,qz\n" + rows + "\n")


def _cli(capsys, monkeypatch, *args: str) -> tuple[int, str, str]:
    from toddlerbot.cli import main as cli_main

    monkeypatch.setattr(sys, "argv", ["toddlerbot", "eval", "tracking", *map(str, args)])
    with pytest.raises(SystemExit) as exc:
        cli_main.main()
    out, err = capsys.readouterr()
    return exc.value.code, out, err


def test_a_capture_of_the_log_recovers_the_offset_and_the_errors(tmp_path):
    log = _synthetic_log()
    write_capture(log, tmp_path / "mocap.csv")
    truth, _ = log_tracking(log, "run.npz")
    result, alignment = log_tracking(log, "run.npz", read_capture(tmp_path / "mocap.csv"))
    assert alignment.offset_s == pytest.approx(OFFSET_S, abs=0.5 / MOCAP_HZ)
    assert alignment.correlation > 0.95
    assert result.position_m == pytest.approx(truth.position_m, abs=0.002)
    assert result.lin_vel_mps == pytest.approx(truth.lin_vel_mps, abs=0.001)
    assert result.ang_vel_radps == pytest.approx(truth.ang_vel_radps, abs=0.003)
    assert truth.ang_vel_radps > 0.01  # the sway is scored: the figures are not trivially zero


def test_a_capture_whose_clock_starts_anywhere_is_found(tmp_path):
    log = _synthetic_log()
    write_capture(log, tmp_path / "mocap.csv", offset_s=-123.45, pad_s=20.0)  # a take started long before
    _, alignment = log_tracking(log, "run.npz", read_capture(tmp_path / "mocap.csv"))
    assert alignment.offset_s == pytest.approx(-123.45, abs=0.5 / MOCAP_HZ)


def test_the_cli_scores_a_logged_run_prints_and_plots(tmp_path, capsys, monkeypatch):
    log = _synthetic_log()
    log.save(tmp_path / "run.npz")
    write_capture(log, tmp_path / "mocap.csv")
    truth, _ = log_tracking(log, "run.npz")
    code, out, _ = _cli(capsys, monkeypatch, "--log", tmp_path / "run.npz", "--mocap", tmp_path / "mocap.csv",
                        "--json", "--plot", tmp_path / "track.png")
    scored = json.loads(out)
    assert code == 0 and scored["falls"] == 0 and scored["ground_truth"] == str(tmp_path / "mocap.csv")
    assert scored["mocap_offset_s"] == pytest.approx(OFFSET_S, abs=0.5 / MOCAP_HZ)
    assert scored["position_m"] == pytest.approx(truth.position_m, abs=0.002)
    assert (tmp_path / "track.png").stat().st_size > 10_000
    code, out, _ = _cli(capsys, monkeypatch, "--log", tmp_path / "run.npz")
    printed = " ".join(out.split())  # as one line, whatever the console's width
    assert code == 0 and printed.startswith(f"walk-rl (run.npz): position {truth.position_m:.3f} m, linear velocity "
                                            f"{truth.lin_vel_mps:.3f} m/s, angular velocity "
                                            f"{truth.ang_vel_radps:.3f} rad/s, falls 0 (12.0 s logged; ground truth "
                                            ), out


def test_refusals_are_one_line(tmp_path, capsys, monkeypatch):
    log = _synthetic_log()
    log.save(tmp_path / "run.npz")
    write_capture(log, tmp_path / "mocap.csv")
    frames = (tmp_path / "mocap.csv").read_text().splitlines()
    times = np.array([float(line.split(",")[0]) for line in frames[1:]])

    def refused(*args: str) -> str:
        code, out, err = _cli(capsys, monkeypatch, "--log", tmp_path / "run.npz", *args)
        assert code == 2 and out == "" and err.count("\n") == 1, (code, out, err)
        return err.strip()

    def capture(name: str, keep) -> str:
        (tmp_path / name).write_text("\n".join([frames[0], *[f for f, t in zip(frames[1:], times) if keep(t)]]))
        return str(tmp_path / name)

    late = capture("late.csv", lambda t: t > OFFSET_S + 3.0)  # started 3 s into the run
    assert re.fullmatch(rf"error: {late} covers log time 3\.0\d-13\.9\d s \(offset \+0\.3(6\d|70) s\), the run in "
                        rf"{tmp_path / 'run.npz'} spans 0\.00-11\.98 s: record from before the run starts until after "
                        "it ends", refused("--mocap", late))
    gap = capture("gap.csv", lambda t: not 5.0 < t < 5.3)
    assert re.fullmatch(rf"error: {gap}: no frame for 0\.3\d s after capture time 4\.99\d s \(log time 4\.6\d s\) "
                        r"inside the run \(1 such gap\(s\)\); gaps up to 0\.1 s are interpolated",
                        refused("--mocap", gap))
    write_capture(log, tmp_path / "weak.csv", conjugate=True)
    assert re.fullmatch(r"error: .*weak\.csv: its yaw rate matches the IMU gyro of .*run\.npz at best with correlation "
                        r"0\.\d\d \(offset [-+]\d+\.\d\d s\), under 0\.7: not a capture of this run, a rigid body that "
                        r"is not the torso, or axes not converted to z up", refused("--mocap", tmp_path / "weak.csv"))

    blind = RunLog(**{**log.__dict__, "base_pos": np.full_like(log.base_pos, np.nan),
                      "base_quat": np.full_like(log.base_quat, np.nan)})
    blind.save(tmp_path / "run.npz")
    assert refused() == (f"error: {tmp_path / 'run.npz'}: no ground-truth pose (a hw run without --mocap logs NaN); "
                         "give the run's motion capture with --mocap FILE.csv")
    assert refused("--seconds", "5") == ("error: --log scores a logged run; --seconds set up a simulated one: give "
                                         "one or the other")
    code, out, err = _cli(capsys, monkeypatch, "--mocap", tmp_path / "mocap.csv")
    assert (code, out, err) == (2, "", "error: --mocap needs --log RUN.npz: the run log of the run the capture "
                                       "watched\n")


def test_a_walk_that_never_turns_is_refused_as_ambiguous(tmp_path):
    """Its yaw rate is the gait's sway alone, the same every cycle: a capture one cycle off matches as well."""
    from toddlerbot.errors import ToddlerbotError

    log = _synthetic_log(turns=False, regular=True)
    write_capture(log, tmp_path / "mocap.csv")
    with pytest.raises(ToddlerbotError, match=r"mocap\.csv: offsets \+0\.3\d s and [-+]\d\.\d\d s match the IMU "
                                              r"gyro of run\.npz almost equally \(correlation \d\.\d\d and "
                                              r"0\.9\d\): the run needs a turn to align on$"):
        log_tracking(log, "run.npz", read_capture(tmp_path / "mocap.csv"))


def test_falls_are_read_from_the_log():
    """A run stopped by a fall ends tilted just short of the fall tilt (the runner stops on the next observation);
    a run with the get-up policy counts each stretch it drove."""
    from toddlerbot.runtime.mocap import log_falls

    log = _synthetic_log()
    assert log_falls(log) == 0
    quat = log.imu_quat.copy()
    quat[-1] = Rotation.from_euler("Y", 0.95).as_quat(scalar_first=True)
    assert log_falls(RunLog(**{**log.__dict__, "imu_quat": quat})) == 1
    recovering = np.zeros(len(log.time))
    recovering[100:150] = recovering[300:400] = 1
    assert log_falls(RunLog(**{**log.__dict__, "recovering": recovering})) == 2


HEADER = "time,x,y,z,qw,qx,qy,qz"


@pytest.mark.parametrize("text,message", [
    ("time,x,y,z,qw,qx,qy\n0,0,0,0,1,0,0\n",
     "line 1: missing column 'qz'; expected the header time,x,y,z,qw,qx,qy,qz (docs/hardware.md, \"Table 7 on the "
     "real robot\")"),
    (f"{HEADER}\n0,0,0,0.3,1,0,0,0\n0.01,abc,0,0.3,1,0,0,0\n", "line 3, field x: 'abc' is not a finite number"),
    (f"{HEADER}\n0,0,0,0.3,1,0,0,0\n0.01,0,nan,0.3,1,0,0,0\n", "line 3, field y: 'nan' is not a finite number"),
    (f"{HEADER}\n0,0,0,0.3,1,0,0,0\n0,0,0,0.3,1,0,0,0\n",
     "line 3, field time: 0 s is not after the previous frame's 0 s (frames must be in time order, without repeats)"),
    (f"{HEADER}\n0,0,0,0.3,1,0,0,0\n\n0.01,0,0,0.3,1,0,0,0.5\n",
     "line 4, fields qw,qx,qy,qz: norm 1.118, not a unit quaternion (|norm - 1| <= 0.01; scalar first: qw,qx,qy,qz)"),
    (f"{HEADER}\n0,120.5,0,300.2,1,0,0,0\n",
     "line 2, field x: 120.5 is more than 100 m from the origin; positions are in metres (divide an export in mm by "
     "1000)"),
    (f"{HEADER}\n0,0,0,0.3,1,0,0,0\n0.01,0,0,0.3\n", "line 3: 4 fields, the header has 8"),
    (f"{HEADER}\n0,0,0,0.3,1,0,0,0\n0.01,,,,,,,\n", ": 1 frames; a capture needs at least 2"),
])
def test_a_malformed_capture_is_one_line_naming_file_line_and_field(tmp_path, text, message):
    from toddlerbot.errors import ToddlerbotError

    path = tmp_path / "mocap.csv"
    path.write_text(text)
    with pytest.raises(ToddlerbotError) as exc:
        read_capture(path)
    assert str(exc.value) == f"{path}{'' if message.startswith(':') else ' '}{message}"


def test_lost_frames_and_extra_columns_are_read(tmp_path):
    path = tmp_path / "mocap.csv"
    path.write_text("\ufeffFrame,Time,X,Y,Z,QW,QX,QY,QZ\n0,0.0,1,2,0.3,1,0,0,0\n1,0.01,,,,,,,\n"
                    "2,0.02,1,2,0.3,0.70710678,0,0,0.70710678\n")
    capture = read_capture(path)
    np.testing.assert_allclose(capture.time, [0.0, 0.02])
    np.testing.assert_allclose(capture.quat[1], [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])


HIL_COMMANDS = "0:0,0,0; 1:0.1,0,0; 3:0,0,0.3; 5.5:0.1,0,-0.2"
"""A short walk with turns both ways, something to align a capture on."""


@pytest.mark.realtime
def test_a_hil_walk_scored_from_its_log_and_from_a_capture_of_it(tmp_path, capsys, monkeypatch):
    """walk-rl walks 8 s through the driver and the HIL emulator, watched by the emulator's motion capture. `eval
    tracking --log` gives the errors `hw run` printed for it (to the printed 3 decimals: the same computation), and a
    capture made from the log's pose, 0.37 s ahead, at 120 Hz with noise, is aligned on the IMU gyro to within one
    frame and gives the same errors within 2 mm, 1 mm/s and 3 mrad/s (measured: 0.5 mm, 0.1 mm/s, 0.5 mrad/s).
    The offset holds while the emulator keeps its 10 ms IMU ticks, as when the test runs alone (`realtime`): at load
    12 on the 2-core VM its IMU lagged its pose by 21 ms instead of 12-13 and the offset came out 11 ms early."""
    pytest.importorskip("dynamixel_sdk")
    from test_hw_hil import _hw_run, _start_emulator, _stop_emulator

    cal_file, log_file = tmp_path / "emulated.yaml", tmp_path / "run.npz"
    proc, port = _start_emulator("--hil", "--write-calibration", str(cal_file))
    try:
        run = _hw_run(port, cal_file, "--imu", "emulator", "--mocap", "emulator", "--log", str(log_file), "--policy",
                      "walk-rl", "--command", HIL_COMMANDS, "--seconds", "8")
    finally:
        report = _stop_emulator(proc)
    seen = f"{run.stdout}{run.stderr}emulator: {report}"
    assert run.returncode in (0, 1) and log_file.exists(), seen  # 1: it fell, and the log ends there
    printed = re.search(r"tracking errors: position ([\d.]+) m, linear velocity ([\d.]+) m/s, angular velocity "
                        r"([\d.]+) rad/s", run.stdout)
    assert printed, seen
    code, out, _ = _cli(capsys, monkeypatch, "--log", log_file, "--json")
    logged = json.loads(out)
    assert code == run.returncode and logged["falls"] == run.returncode, seen
    for key, value in zip(("position_m", "lin_vel_mps", "ang_vel_radps"), printed.groups(), strict=True):
        assert logged[key] == pytest.approx(float(value), abs=0.0005 + 1e-9), (key, seen)

    write_capture(RunLog.load(log_file), tmp_path / "mocap.csv")
    code, out, _ = _cli(capsys, monkeypatch, "--log", log_file, "--mocap", tmp_path / "mocap.csv", "--json")
    captured = json.loads(out)
    assert captured["mocap_offset_s"] == pytest.approx(OFFSET_S, abs=1 / MOCAP_HZ), (captured, seen)
    assert captured["position_m"] == pytest.approx(logged["position_m"], abs=0.002), (captured, logged)
    assert captured["lin_vel_mps"] == pytest.approx(logged["lin_vel_mps"], abs=0.001), (captured, logged)
    assert captured["ang_vel_radps"] == pytest.approx(logged["ang_vel_radps"], abs=0.003), (captured, logged)
