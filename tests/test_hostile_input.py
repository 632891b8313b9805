"""Hostile input files, table-driven: robot spec, motor catalogue, motion files and exported policies.

Each bad file gets a one-line `ToddlerbotError` subclass that starts with the file's path; nothing else
(traceback, MemoryError, minutes of parsing) happens."""

from __future__ import annotations

import re
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from cli_support import one_line_error, run_main
from toddlerbot.actuation.catalogue import DEFAULT_CATALOGUE, load_catalogue
from toddlerbot.errors import SpecError, ToddlerbotError
from toddlerbot.policies.motions import MotionError, load_motion
from toddlerbot.policies.rl_inference import RLPolicyFile
from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS
from toddlerbot.robot.spec import DEFAULT_SPEC, load_spec

SPEC_TEXT = Path(str(DEFAULT_SPEC)).read_text()
CATALOGUE_TEXT = Path(str(DEFAULT_CATALOGUE)).read_text()
ALIAS_BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(7)
)
"""Ten to the eighth power leaves from 8 lines of text."""


def _one_line_error(exc: BaseException, path: Path) -> str:
    message = str(exc)
    assert message.startswith(str(path)) and "\n" not in message, message
    return message


TORSO = "bodies[0] (torso)."
FINITE = "Input should be a finite number"
SPEC_CASES = [
    ("nan_com", SPEC_TEXT.replace("com: [-0.00261802,", "com: [.nan,", 1), TORSO + "com[0]: " + FINITE),
    ("inf_mass", SPEC_TEXT.replace("mass: 1.08507", "mass: .inf", 1), TORSO + "mass: " + FINITE),
    ("nan_inertia", SPEC_TEXT.replace("inertia: [0.00283944,", "inertia: [.nan,", 1), TORSO + "inertia[0]: " + FINITE),
    ("inf_inertia", SPEC_TEXT.replace("inertia: [0.00283944,", "inertia: [.inf,", 1), TORSO + "inertia[0]: " + FINITE),
    ("nan_range", SPEC_TEXT.replace("range: [-1.74533, 0.785398]", "range: [.nan, 0.785398]", 1),
     "range[0]: " + FINITE),
    ("negative_mass", SPEC_TEXT.replace("mass: 1.08507", "mass: -1.0", 1), TORSO + "mass: Input should be greater"),
    # finite but absurd: plausible ranges, not only finite
    ("huge_mass", SPEC_TEXT.replace("mass: 1.08507", "mass: 1.0e+308", 1),
     TORSO + "mass: Input should be less than or equal to 1000"),
    ("huge_inertia", SPEC_TEXT.replace("inertia: [0.00283944,", "inertia: [1.0e+300,", 1),
     TORSO + "inertia: principal inertias must lie in (0, 100] kg*m^2, got (1e+300,"),
    ("huge_timestep", SPEC_TEXT.replace("timestep: 0.001", "timestep: 1.0e+300", 1),
     "simulation.timestep: Input should be less than or equal to 0.05"),
    ("zero_timestep", SPEC_TEXT.replace("timestep: 0.001", "timestep: 1.0e-300", 1),
     "simulation.timestep: Input should be greater than or equal to 0.00001"),
    ("truncated", SPEC_TEXT[: len(SPEC_TEXT) // 3] + "\n  - [", "not valid YAML"),
    ("empty", "", "expected a mapping at the top level"),
    ("alias_bomb", ALIAS_BOMB, "YAML aliases expand to more than 1000000 nodes"),
]


@pytest.mark.parametrize(("name", "text", "expected"), SPEC_CASES, ids=[c[0] for c in SPEC_CASES])
def test_hostile_specs_get_one_line_errors(tmp_path, name, text, expected):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert expected in _one_line_error(info.value, path)


def test_binary_and_oversized_specs_are_refused_quickly(tmp_path):
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"name: x\n\xff\xfe\x00\x81")
    with pytest.raises(SpecError, match=r"not UTF-8 text \(byte 8\)"):
        load_spec(binary)
    huge = tmp_path / "huge.yaml"
    with huge.open("w") as f:
        f.write(SPEC_TEXT)
        f.write("# padding\n" * 5_000_000)  # 50 MB
    start = time.perf_counter()
    with pytest.raises(SpecError, match=r"50\d{6} bytes is too large for a robot spec \(at most 4000000 bytes\)"):
        load_spec(huge)
    assert time.perf_counter() - start < 1.0


CATALOGUE_CASES = [
    ("nan_damping", CATALOGUE_TEXT.replace("damping: 0.0036", "damping: .nan", 1), "damping"),
    ("inf_armature", CATALOGUE_TEXT.replace("armature: 0.0040", "armature: .inf", 1), "armature"),
    ("bool_param", CATALOGUE_TEXT.replace("tau_max: 0.76", "tau_max: true", 1), "tau_max"),
    ("huge_tau_max", CATALOGUE_TEXT.replace("tau_max: 0.76", "tau_max: 1.0e+300", 1),
     "tau_max must be at most 1000, got 1e+300"),
    ("nan_stall_torque", re.sub(r"(\n\s+stall_torque_nm: )[0-9.]+", r"\1.nan", CATALOGUE_TEXT, count=1),
     "stall_torque_nm must lie in [0.001, 1000], got nan"),
    ("alias_bomb", ALIAS_BOMB, "YAML aliases expand"),
    ("empty", "", ""),
]


@pytest.mark.parametrize(("name", "text", "expected"), CATALOGUE_CASES, ids=[c[0] for c in CATALOGUE_CASES])
def test_hostile_motor_catalogues_get_one_line_errors(tmp_path, name, text, expected):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    with pytest.raises(SpecError) as info:
        load_catalogue(path)
    assert expected in _one_line_error(info.value, path)


MOTION = """name: m
joints: [left_knee]
keyframes:
  - {t: 0.0, left_knee: 0}
  - {t: T1, left_knee: A1}
  - {t: 2.0, left_knee: -10}
"""
MOTION_CASES = [
    ("nan_time", {"T1": ".nan", "A1": "-5"}, "keyframe 1: t must be a finite number of seconds, got nan"),
    ("inf_time", {"T1": ".inf", "A1": "-5"}, "keyframe 1: t must be a finite number of seconds, got inf"),
    ("text_time", {"T1": "soon", "A1": "-5"}, "keyframe 1: t must be a finite number of seconds, got 'soon'"),
    ("bool_time", {"T1": "true", "A1": "-5"}, "got True"),
    ("decreasing", {"T1": "3.0", "A1": "-5"}, "keyframe times must start at 0 and increase"),
    ("repeated", {"T1": "0.0", "A1": "-5"}, "keyframe times must start at 0 and increase"),
    ("nan_angle", {"T1": "1.0", "A1": ".nan"}, "left_knee must be a number of degrees, got nan"),
    ("bool_angle", {"T1": "1.0", "A1": "true"}, "left_knee must be a number of degrees, got True"),
]


@pytest.mark.parametrize(("name", "fields", "expected"), MOTION_CASES, ids=[c[0] for c in MOTION_CASES])
def test_hostile_motion_files_get_one_line_errors(tmp_path, name, fields, expected, description):
    text = MOTION.replace("T1", fields["T1"]).replace("A1", fields["A1"])
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    with pytest.raises(MotionError) as info:
        load_motion(str(path), description)
    assert expected in _one_line_error(info.value, path)


def _weights(**changes) -> dict[str, np.ndarray]:
    data = dict(np.load(DEFAULT_WEIGHTS, allow_pickle=False))
    return data | changes


WEIGHT_CASES = [
    ("nan_last_layer", lambda d: d | {"layer3_kernel": np.full_like(d["layer3_kernel"], np.nan)},
     "layer3_kernel holds non-finite values"),
    ("inf_bias", lambda d: d | {"layer0_bias": np.full_like(d["layer0_bias"], np.inf)},
     "layer0_bias holds non-finite values"),
    ("zero_std", lambda d: d | {"obs_std": np.zeros_like(d["obs_std"])}, "obs_std must be positive"),
    ("wrong_shape", lambda d: d | {"layer2_kernel": d["layer2_kernel"][:, :7]},
     "layer2 has kernel (128, 7) and bias (64,)"),
    ("missing_layer", lambda d: {k: v for k, v in d.items() if k != "layer1_bias"}, "missing 'layer1_bias'"),
    ("bad_index", lambda d: d | {"leg_motor_index": d["leg_motor_index"] + 100}, "leg_motor_index must hold"),
    ("bad_json", lambda d: d | {"meta": np.array("{not json")}, "malformed exported policy"),
]


@pytest.mark.parametrize(("name", "change", "expected"), WEIGHT_CASES, ids=[c[0] for c in WEIGHT_CASES])
def test_hostile_policy_weights_get_one_line_errors(tmp_path, name, change, expected):
    path = tmp_path / f"{name}.npz"
    np.savez(path, **change(_weights()))
    with pytest.raises(ToddlerbotError) as info:
        RLPolicyFile(path)
    assert expected in _one_line_error(info.value, path)


def test_empty_truncated_pickled_and_foreign_weight_files(tmp_path):
    cases = {"empty.npz": b"", "truncated.npz": DEFAULT_WEIGHTS.read_bytes()[:5000], "text.npz": b"hello\n"}
    for name, content in cases.items():
        (tmp_path / name).write_bytes(content)
    np.savez(tmp_path / "pickled.npz", obj=np.array([{"a": 1}], dtype=object))
    np.save(tmp_path / "single.npy", np.zeros(3))
    expected = {"empty.npz": "empty file", "truncated.npz": "not a readable .npz file",
                "text.npz": "not a readable .npz file", "pickled.npz": "not a readable .npz file",
                "single.npy": "a single .npy array"}
    for name, message in expected.items():
        with pytest.raises(ToddlerbotError) as info:
            RLPolicyFile(tmp_path / name)
        assert message in _one_line_error(info.value, tmp_path / name)


def _run_log(n: int = 5):
    from toddlerbot.runtime.log import LogRecorder

    recorder = LogRecorder()
    names = ("a", "b")
    for k in range(n):
        recorder.append(time=0.02 * k, command=np.zeros(3), motor_pos=np.zeros(2), motor_vel=np.zeros(2),
                        motor_torque=np.zeros(2), joint_pos=np.zeros(2), joint_vel=np.zeros(2),
                        motor_target=np.zeros(2), joint_target=np.zeros(2), imu_quat=np.array([1.0, 0, 0, 0]),
                        imu_ang_vel=np.zeros(3), imu_lin_acc=np.zeros(3), foot_contact=np.zeros(2, bool),
                        base_pos=np.full(3, np.nan), base_quat=np.full(4, np.nan), compute_time=0.001,
                        step_period=0.02)
    return recorder.finish(names, names, 0.02, "stand")


def test_hostile_run_logs_get_one_line_errors(tmp_path):
    from toddlerbot.runtime.log import RunLog

    good = _run_log().save(tmp_path / "good.npz")
    assert RunLog.load(good).time.size == 5  # NaN ground truth (hardware) is allowed
    arrays = dict(np.load(good, allow_pickle=False))
    cases = {
        "empty.npz": b"", "truncated.npz": good.read_bytes()[:200],
        "nan_time.npz": arrays | {"time": np.array([0.0, np.nan, 0.04, 0.06, 0.08])},
        "backwards.npz": arrays | {"time": arrays["time"][::-1]},
        "short_rows.npz": arrays | {"motor_pos": arrays["motor_pos"][:3]},
        "wide.npz": arrays | {"joint_pos": np.zeros((5, 7))},
        "bad_dt.npz": arrays | {"control_dt": np.array(np.inf)},
        "pickled.npz": arrays | {"policy": np.array([{"x": 1}], dtype=object)},
    }
    expected = {"empty.npz": "is not a run log", "truncated.npz": "is not a run log",
                "nan_time.npz": "'time' must be finite and non-decreasing", "backwards.npz": "'time' must be finite",
                "short_rows.npz": "'motor_pos' has shape (3, 2)", "wide.npz": "'joint_pos' has shape (5, 7)",
                "bad_dt.npz": "control_dt must be a finite period", "pickled.npz": "is not a run log"}
    for name, content in cases.items():
        path = tmp_path / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            np.savez(path, **content)
        with pytest.raises(ToddlerbotError) as info:
            RunLog.load(path)
        assert expected[name] in _one_line_error(info.value, path)


# ---- hostile command lines: each is one line on stderr and exit code 2, before any work starts ---------------------
PARAMS_1E300 = '{"motor": "XC330", "actuator": {"tau_max": 1e300}}'
CLI_CASES = [
    # output paths: a folder, a file where a folder is expected, an unwritable place, a special file
    ("model_build_dir", "model build -o {dir}", "--output {dir}: is a directory, expected the name of a regular file"),
    ("manip_demo_file", "manip demo -o {file}", "--out {file}: is not a folder, expected a folder to write into"),
    ("sim_plot_file", "sim plot {file} -o {file}", "--out {file}: is not a folder"),
    ("dp_eval_video_dir", "dp eval --video {dir}", "--video {dir}: is a directory"),
    ("eval_plot_dir", "eval tracking --plot {dir}", "--plot {dir}: is a directory"),
    ("sysid_fit_dir", "sysid fit {file} -o {dir}", "--output {dir}: is a directory"),
    ("sim_log_proc", "sim run --policy stand --log /proc/self/run.npz",
     "--log /proc/self/run.npz: cannot write there ("),
    ("sim_log_missing_folder", "sim run --policy stand --log {dir}/nonexistent/sub/run.npz",
     "--log {dir}/nonexistent/sub/run.npz: folder {dir}/nonexistent/sub does not exist; create it first"),
    ("sim_summary_proc", "sim run --policy stand --summary-json /proc/version",
     "--summary-json /proc/version: cannot write there ("),
    ("sim_video_devnull", "sim run --policy stand --video /dev/null",
     "--video /dev/null: is a special file, expected the name of a regular file to write"),
    ("sim_log_under_file", "sim run --policy stand --log {file}/run.npz",
     "--log {file}/run.npz: cannot write there ({file} is not a folder)"),
    ("design_plot_file", "design report --plot {file}", "--plot {file}: is not a folder"),
    ("chain_video_dir", "chain run wagon --video {dir}", "--video {dir}: is a directory"),
    ("emulate_calibration_dir", "hw emulate --write-calibration {dir}", "--write-calibration {dir}: is a directory"),
    ("hw_log_dir", "hw run --port /dev/ttyNOPE --calibration {cal} --log {dir}", "--log {dir}: is a directory"),
    # numbers a run cannot use
    ("control_hz_1e9", "sim run --policy stand --control-hz 1e9",
     "--control-hz 1e+09: expected the 1000 Hz physics rate divided by a whole number, e.g. 50"),
    ("control_hz_3", "sim run --policy stand --control-hz 3", "--control-hz 3: expected the 1000 Hz physics rate"),
    ("eval_seconds_nan", "eval tracking --seconds nan", "--seconds nan: expected a duration in (0, 3600] seconds"),
    ("sim_seconds_1e300", "sim run --policy stand --seconds 1e300",
     "--seconds 1e+300: expected a duration in (0, 3600]"),
    ("hw_seconds_1e300", "hw run --port /dev/ttyNOPE --calibration {cal} --seconds 1e300",
     "--seconds 1e+300: expected"),
    ("hw_walk_zmp_dt_1e-9", "hw run --port /dev/ttyNOPE --calibration {cal} --policy walk-zmp --dt 1e-9",
     "walk-zmp cannot plan at a control period of 1e-09 s: its 1.2 s preview would be 1200000000 ticks (at most 2400)"),
    ("sim_camera_unknown", "sim run --policy stand --seconds 0.1 --camera nonexistent --video {dir}/v.mp4",
     "camera 'nonexistent' is not in the model; expected one of "),
    ("sim_walk_zmp_2_hz", "sim run --policy walk-zmp --control-hz 2",
     "walk-zmp cannot plan at a control period of 0.5 s: cycle_time 0.6 s and double_support_ratio 0.25 leave no"),
    ("design_height_nan", "design report --height nan", "--height nan: expected a number of m in [0.1, 2.5]"),
    ("design_height_inf", "design report --height inf --json", "--height inf: expected a number of m in [0.1, 2.5]"),
    ("design_mass_1e308", "design report --mass 1e308", "--mass 1e+308: expected a number of kg in [0.05, 300]"),
    ("design_battery_nan", "design report --battery-ah nan", "battery_capacity_ah must be in (0, 1000], got nan"),
    ("dp_train_steps_negative", "dp train {dir} -o {dir}/run --steps -5", "--steps -5: expected a whole number >= 1"),
    ("dp_train_minutes_nan", "dp train {dir} -o {dir}/run --minutes nan",
     "--minutes nan: expected a duration in (0, 10080] minutes"),
    ("rl_train_minutes_inf", "rl train --minutes inf", "--minutes inf: expected a duration in (0, 10080]"),
    ("rl_train_epochs_zero", "rl train --epochs 0", "--epochs 0: expected a whole number >= 1"),
    ("teleop_leader_rate_nan", "teleop leader --port /dev/ttyNOPE --calibration {cal} --rate nan",
     "--rate nan: expected a number of Hz in [0.1, 1000]"),
    ("chain_seed_negative", "chain run wagon --seed -1",
     "toddlerbot chain run: Invalid value for '--seed': Input should be greater than or equal to 0"),
    ("chain_variation_unknown", "chain run wagon --variation windy",
     "task 'wagon' has no scene variation 'windy'; expected one of default, wide"),
    ("chain_variation_on_hardware", "chain run wagon --port /dev/ttyNOPE --calibration {cal} --variation wide",
     "--variation 'wide' draws a simulated scene; the real robot has its own"),
    ("manip_demo_variation_unknown", "manip demo --task pick:wide -o {dir}/ds",
     "task 'pick' has no scene variation 'wide'; expected one of default"),
    ("sim_seed_too_large", "sim run --policy stand --task pick --seed 4294967296",
     "Invalid value for '--seed': Input should be less than or equal to 4294967295"),
    ("rl_train_hand_force_1e308", "rl train --smoke --hand-force 1e308 --out {dir}/run",
     "--hand-force: hand_force 1e+308: expected a force in [0, 30] N"),
    ("rl_train_push_velocity_1e9", "rl train --smoke --push-velocity 0 1e9 --out {dir}/run",
     "expected 0 <= smallest <= largest <= 3 m/s"),
    ("rl_train_num_envs_1e9", "rl train --smoke --num-envs 1000000000 --out {dir}/run",
     "1000000000 envs: expected 1-65,536"),
    ("rl_train_timesteps_1e14", "rl train --smoke --timesteps 100000000000000 --out {dir}/run",
     "100000000000000 env steps: expected 1-2,147,483,647 (a 32-bit step counter)"),
    ("rl_train_solver_iterations_1e6", "rl train --smoke --solver-iterations 1000000 --out {dir}/run",
     "solver iterations 1000000/8: expected 1-100"),
    ("rl_train_imitation_iterations_1e8", "rl train --smoke --imitation-iterations 100000000 --out {dir}/run",
     "--imitation-iterations 100000000: ImitationConfig: iterations 0-1000"),
    ("sysid_excite_duration_1e9", "sysid excite -o {dir}/run --duration 1e9",
     "--duration 1e+09: expected a duration in (0, 3600] seconds"),
    ("sysid_excite_kp_negative", "sysid excite -o {dir}/run --kp -5",
     "--kp -5: expected a number of firmware units in [0, 16383]"),
    # input files: not UTF-8, endless, absurd values
    ("command_file_binary", "sim run --policy stand --command-file {binary}", "{binary}: not UTF-8 text (byte 2)"),
    ("sysid_manifest_binary", "sysid fit {binary} -o {dir}/params.json", "{binary}: not UTF-8 text (byte 2)"),
    ("sysid_manifest_dev_zero", "sysid fit /dev/zero -o {dir}/params.json",
     "/dev/zero: more than 1000000 bytes is too large for a manifest (at most 1000000 bytes)"),
    ("params_dev_zero", "model info --motor-params /dev/zero",
     "/dev/zero: more than 1048576 bytes is too large for a params.json"),
    ("chain_file_passwd", "chain run {passwd}",
     "{passwd}: the file: expected a mapping, got 'user0:x:0:0:User:/home/u0"),
    ("command_file_dev_zero", "sim run --policy stand --command-file /dev/zero",
     "/dev/zero: more than 1000000 bytes is too large for a command file (at most 1000000 bytes)"),
    ("run_log_dev_zero", "eval tracking --log /dev/zero",
     "/dev/zero is not a run log (.npz with the keys of toddlerbot.runtime.log): not a regular file"),
    ("spec_mass_1e308", "model info --spec {huge_mass}", "bodies[0] (torso).mass: Input should be less than or equal"),
    ("spec_timestep_1e300", "model build --spec {huge_timestep} -o {dir}/robot.xml",
     "simulation.timestep: Input should be less than or equal to 0.05"),
    ("params_tau_max_1e300", "model info --motor-params {params}",
     "{params}: tau_max must be at most 1000, got 1e+300"),
    # typer's own option errors: one line, not a 5-line box
    ("typer_not_a_number", "sim run --seconds abc",
     "toddlerbot sim run: Invalid value for '--seconds': Input should be a valid number"),
    ("typer_unknown_option", "sim run --bogus", "toddlerbot sim run: No such option: --bogus"),
    ("typer_missing_option", "model build", "toddlerbot model build: Missing option '-o' / '--output'."),
]


@pytest.fixture(scope="module")
def cli_files(tmp_path_factory):
    from toddlerbot.hardware.calibration import Calibration, save_calibration
    from toddlerbot.robot.description import RobotDescription

    root = tmp_path_factory.mktemp("cli")
    files = {"dir": root / "a_dir", "file": root / "a_file", "cal": root / "cal.yaml", "binary": root / "cmd.txt",
             "huge_mass": root / "huge_mass.yaml", "huge_timestep": root / "huge_timestep.yaml",
             "params": root / "params.json", "passwd": root / "passwd"}
    files["dir"].mkdir()
    files["file"].write_text("x")
    save_calibration(Calibration("tb", "toddlerbot_v1", {n: 2048 for n in RobotDescription.load().motor_names}),
                     files["cal"])
    files["binary"].write_bytes(b"0:\xff\xfe0.1,0,0\n")
    files["huge_mass"].write_text(SPEC_TEXT.replace("mass: 1.08507", "mass: 1.0e+308", 1))
    files["huge_timestep"].write_text(SPEC_TEXT.replace("timestep: 0.001", "timestep: 1.0e+300", 1))
    files["params"].write_text(PARAMS_1E300)
    files["passwd"].write_text("".join(f"user{i}:x:{i}:{i}:User:/home/u{i}:/bin/sh\n" for i in range(200)))
    return {k: str(v) for k, v in files.items()}


@pytest.mark.parametrize(("name", "command", "expected"), CLI_CASES, ids=[c[0] for c in CLI_CASES])
def test_hostile_command_lines_get_one_line_errors_and_exit_2(name, command, expected, cli_files, capsys,
                                                              monkeypatch):
    if name.startswith("dp_"):
        pytest.importorskip("torch")
    code, out, err = run_main(monkeypatch, capsys, *command.format(**cli_files).split())
    line = one_line_error(code, err)
    assert "Traceback" not in out and expected.format(**cli_files) in line, line
    assert len(line) < 400  # a file is named and quoted by at most about 60 characters, never printed whole
    assert not (Path(cli_files["dir"]) / "run").exists()  # nothing created by a refused training run


def test_real_use_stays_within_the_ranges(cli_files, capsys, monkeypatch):
    """What-if designs up to 1.8 m tall, two hours of training, and `stand` at the signal benchmark's 1 ns period
    are all accepted; design JSON never holds NaN or Infinity."""
    import json

    from toddlerbot.cli.options import training_budget
    from toddlerbot.hardware.calibration import Calibration
    from toddlerbot.hardware.real_robot import RealRobot
    from toddlerbot.policies import make_policy
    from toddlerbot.robot.description import RobotDescription

    code, out, _ = run_main(monkeypatch, capsys, "design", "report", "--height", "1.8", "--mass", "70", "--json")
    assert code == 0
    report = json.loads(out, parse_constant=lambda token: pytest.fail(f"non-JSON token {token}"))
    assert report["height_m"] == 1.8 and report["mass_kg"] == 70.0
    training_budget(120.0, None)
    description = RobotDescription.load()
    robot = RealRobot(description, "/dev/ttyNOPE", Calibration("tb", "toddlerbot_v1", {
        n: 2048 for n in description.motor_names}), control_dt=1e-9)  # no port is opened
    assert make_policy("stand", robot).name == "stand"


def test_a_run_log_that_expands_beyond_the_cap_is_refused_before_decompressing(tmp_path, monkeypatch):
    from toddlerbot.runtime import log as run_log

    path = _run_log(n=200).save(tmp_path / "log.npz")
    with zipfile.ZipFile(path) as archive:
        expanded = sum(i.file_size for i in archive.infolist())
    monkeypatch.setattr(run_log, "MAX_RUN_LOG_BYTES", expanded - 1)  # a 1 GiB cap, scaled down to this log
    with pytest.raises(ToddlerbotError) as info:
        run_log.RunLog.load(path)
    assert f"expands to {expanded} bytes; a run log has at most {expanded - 1} bytes" in _one_line_error(info.value,
                                                                                                      path)
