"""No command overwrites what it reads, writes into the installed package, or creates a folder a typo named: each is
refused in one line before any work, and the input is byte for byte what it was."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cli_support import one_line_error, run_main
from toddlerbot.cli import output_paths
from toddlerbot.robot.spec import DEFAULT_SPEC


@pytest.fixture(scope="module")
def sysid_logs(tmp_path_factory) -> Path:
    """A manifest and two synthetic logs (`sysid excite --simulate`)."""
    from typer.testing import CliRunner

    from toddlerbot.cli.main import app

    folder = tmp_path_factory.mktemp("sysid") / "logs"
    result = CliRunner().invoke(app, ["sysid", "excite", "-o", str(folder), "--profile", "steps", "--profile",
                                      "chirp", "--kp", "400", "--duration", "1", "--simulate"])
    assert result.exit_code == 0, result.output
    return folder


def _refused(monkeypatch, capsys, protected: Path, *args) -> str:
    before = protected.read_bytes()
    code, _, err = run_main(monkeypatch, capsys, *args)
    line = one_line_error(code, err)
    assert protected.read_bytes() == before
    return line


def test_sysid_fit_refuses_to_write_over_a_log_of_its_manifest(sysid_logs, monkeypatch, capsys):
    log = sysid_logs / "steps_kp400.csv"
    line = _refused(monkeypatch, capsys, log, "sysid", "fit", sysid_logs / "manifest.json", "-o", log)
    assert line == f"error: --output {log}: would overwrite this command's input {log}; write elsewhere"


def test_sysid_fit_refuses_to_write_over_its_manifest(sysid_logs, monkeypatch, capsys):
    manifest = sysid_logs / "manifest.json"
    line = _refused(monkeypatch, capsys, manifest, "sysid", "fit", manifest, "-o", manifest)
    assert f"--output {manifest}: would overwrite this command's input {manifest}" in line


def test_a_hard_link_to_an_input_is_the_input(sysid_logs, monkeypatch, capsys, tmp_path):
    link = tmp_path / "params.json"
    os.link(sysid_logs / "chirp_kp400.csv", link)
    line = _refused(monkeypatch, capsys, sysid_logs / "chirp_kp400.csv", "sysid", "fit",
                    sysid_logs / "manifest.json", "-o", link)
    assert "would overwrite this command's input" in line and "chirp_kp400.csv" in line


def test_a_manifest_listing_one_log_twice_is_refused(sysid_logs, monkeypatch, capsys, tmp_path):
    """The same CSV at two gains would weigh one run twice and hide the fit's error (1,960 % standard error)."""
    import json

    twice = json.loads((sysid_logs / "manifest.json").read_text())
    first = twice["logs"][0]["file"]
    twice["logs"] = [{"file": first, "kp": 400}, {"file": f"./{first}", "kp": 1200}]
    manifest = sysid_logs / "twice.json"
    manifest.write_text(json.dumps(twice))
    code, _, err = run_main(monkeypatch, capsys, "sysid", "fit", manifest, "-o", tmp_path / "params.json")
    assert one_line_error(code, err) == (f"error: {manifest}: logs[1] names './{first}', which logs[0] already "
                                         "names; each log may be listed once")
    assert not (tmp_path / "params.json").exists()


def test_a_log_beyond_its_size_cap_is_refused_unread(sysid_logs, monkeypatch, capsys, tmp_path):
    from toddlerbot.sysid import logs

    monkeypatch.setattr(logs, "MAX_LOG_BYTES", 1000)  # the synthetic logs are about 4 kB
    code, _, err = run_main(monkeypatch, capsys, "sysid", "fit", sysid_logs / "manifest.json", "-o",
                            tmp_path / "params.json")
    assert "is too large for a log (at most 1000 bytes)" in one_line_error(code, err)


def test_sim_run_refuses_a_log_over_its_command_file(monkeypatch, capsys, tmp_path):
    schedule = tmp_path / "schedule.txt"
    schedule.write_text("0: 0.1, 0, 0\n")
    line = _refused(monkeypatch, capsys, schedule, "sim", "run", "--policy", "stand", "--command-file", schedule,
                    "--log", schedule)
    assert f"--log {schedule}: would overwrite this command's input {schedule}" in line


def test_model_build_refuses_to_write_over_its_spec(monkeypatch, capsys, tmp_path):
    spec = tmp_path / "robot.yaml"
    spec.write_bytes(Path(str(DEFAULT_SPEC)).read_bytes())
    line = _refused(monkeypatch, capsys, spec, "model", "build", "--spec", spec, "-o", spec)
    assert f"--output {spec}: would overwrite this command's input {spec}" in line


def test_no_command_writes_into_the_installed_package(monkeypatch, capsys):
    target = output_paths.PACKAGE_DIR / "robot" / "specs" / "robot.xml"
    code, _, err = run_main(monkeypatch, capsys, "model", "build", "-o", target)
    assert f"--output {target}: is inside the installed toddlerbot package" in one_line_error(code, err)
    assert not target.exists()


def test_a_missing_output_folder_is_refused_not_created(monkeypatch, capsys, tmp_path):
    """One rule for every command: the folder holding an output must exist (a typo is not a new tree)."""
    for args, option in ((["sim", "run", "--policy", "stand", "--log"], "--log"),
                         (["model", "build", "-o"], "--output"),
                         (["sim", "run", "--policy", "stand", "--video"], "--video")):
        target = tmp_path / "typo" / "sub" / "out.file"
        code, _, err = run_main(monkeypatch, capsys, *args, target)
        assert one_line_error(code, err) == (f"error: {option} {target}: folder {target.parent} does not exist; "
                                             f"create it first (mkdir -p {target.parent})")
    code, _, err = run_main(monkeypatch, capsys, "sim", "plot", tmp_path / "x.npz", "-o", tmp_path / "a" / "b")
    assert f"--out {tmp_path / 'a' / 'b'}: folder {tmp_path / 'a'} does not exist" in one_line_error(code, err)
    assert not (tmp_path / "typo").exists() and not (tmp_path / "a").exists()


def test_an_output_folder_may_be_new_when_its_parent_exists(monkeypatch, capsys, tmp_path):
    code, _, err = run_main(monkeypatch, capsys, "design", "report", "--plot", tmp_path / "figures")
    assert code == 0, err
    assert len(list((tmp_path / "figures").glob("*.png"))) >= 3


def test_a_dataset_is_never_written_into_a_folder_that_holds_something(monkeypatch, capsys, tmp_path):
    """`manip demo` and `teleop` write a dataset whole: a folder with files in it is refused by the one output check
    (the demonstrations replace it only with --overwrite), and its files are untouched."""
    full = tmp_path / "full"
    full.mkdir()
    (full / "notes.txt").write_text("mine")
    code, _, err = run_main(monkeypatch, capsys, "manip", "demo", "-o", full, "--episodes", "1")
    assert one_line_error(code, err) == f"error: --out {full}: exists and is not empty; pass --overwrite to replace it"
    code, _, err = run_main(monkeypatch, capsys, "teleop", "--out", full, "--seconds", "1")
    assert one_line_error(code, err) == f"error: --out {full}: exists and is not empty; record into a new folder"
    assert (full / "notes.txt").read_text() == "mine"


def test_a_commands_own_default_location_is_created_but_a_typed_one_is_not(tmp_path):
    """`rl train` without --out writes runs/rl/<time>, whose folders a fresh checkout lacks: the command's own
    default is created (`default=True`); the same path typed by the user is held to the rule."""
    from toddlerbot.errors import ToddlerbotError

    run = tmp_path / "runs" / "rl" / "20261128-120000"
    with pytest.raises(ToddlerbotError, match="does not exist; create it first"):
        output_paths.output_dir(run, "--out")
    assert not (tmp_path / "runs").exists()
    assert output_paths.output_dir(run, "--out", default=True) == run and run.parent.is_dir() and not run.exists()
