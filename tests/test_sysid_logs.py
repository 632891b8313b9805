"""Bad logs and manifests: a clear error naming the file and the problem; nothing partially written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.manifest import load_manifest
from toddlerbot.sysid.rigs import PendulumRig
from toddlerbot.sysid.rigs import TestBedRig as BedRig

GOOD = "time,goal_position,position,velocity\n0,0,0,0\n0.005,0.1,0.001,0.2\n0.010,0.1,0.003,0.4\n"


def _manifest(tmp_path: Path, csv_text: str = GOOD, **overrides) -> Path:
    (tmp_path / "run1.csv").write_text(csv_text)
    body = {"motor": "XC330", "rig": {"type": "pendulum", "mass": 0.49, "length": 0.1},
            "logs": [{"file": "run1.csv", "kp": 400, "kd": 0}], **overrides}
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps(body))
    return path


def test_good_manifest_loads(tmp_path: Path) -> None:
    m = load_manifest(_manifest(tmp_path))
    assert m.motor.name == "XC330-T288"
    assert m.rig == PendulumRig(mass=0.49, length=0.1)
    assert m.rig.load_inertia == pytest.approx(0.49 * 0.01)
    run = m.runs[0]
    assert (run.kp, run.kd, run.initial_velocity) == (400.0, 0.0, 0.0)
    assert list(run.position) == [0.0, 0.001, 0.003]


def test_yaml_manifest_and_testbed_rig(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text(GOOD)
    (tmp_path / "m.yaml").write_text("motor: XM430\nrig: {type: testbed, load_inertia: 0.002, brake_torque: 0.5}\n"
                                     "logs:\n- {file: a.csv, kp: 900}\n")
    m = load_manifest(tmp_path / "m.yaml")
    assert m.rig == BedRig(load_inertia=0.002, brake_torque=0.5)
    assert m.runs[0].kd == 0.0


HEAD = "time,goal_position,position"


def _rows(*rows: str, head: str = HEAD) -> str:
    return "\n".join((head, *rows)) + "\n"


@pytest.mark.parametrize(
    ("csv_text", "message"),
    [
        (_rows("0,0,0", "0.01,0,0", "0.005,0,0"), r"run1.csv: line 4: time is not strictly increasing"),
        (_rows("0,0,0", "0.01,nan,0"), r"run1.csv: line 3: column 'goal_position' is NaN/inf"),
        (_rows("0,0", "0.01,0", head="time,position"), r"run1.csv: missing column\(s\) goal_position"),
        (_rows("0,0,0", "0.01,abc,0"), r"run1.csv: line 3: column 'goal_position' is not a"),
        (_rows("0,0,0"), r"run1.csv: needs at least 2 samples"),
        # time in ms (5 ms steps logged as 5, 10, ...)
        (_rows("0,0,0", "5,0,0", "10,0,0"), r"run1.csv: column .time.: median sample step 5 s .* \(this looks like ms"),
        # the 1e9 s gap that would make the replay allocate terabytes
        (_rows("0,0,0", "0.005,0,0", "0.01,0,0", "1e9,0,0"), r"run1.csv: line 5: column 'time' jumps 1e\+09 s"),
        (_rows("0,0,0", "0.005,1e300,0", "0.01,0,0"), r"run1.csv: line 3: column 'goal_position' is 1e\+300"),
        (_rows("0,0,0", "0.005,0,-1e300", "0.01,0,0"), r"run1.csv: line 3: column 'position' is -1e\+300"),
        # degrees instead of radians: refused, not fitted
        (_rows("0,0,0", "0.005,30,2", "0.01,45,20"), r"run1.csv: line 4: column 'position' is 20; .*not degrees"),
        (_rows("0,0,0,0", "0.005,0,0,300", "0.01,0,0,0", head=HEAD + ",velocity"),
         r"run1.csv: line 3: column 'velocity' is 300; .*rad/s, not deg/s or rpm"),
        (_rows("0,0,0,1", "0.005,0,0,2", "0.01,0,0,0", head=HEAD + ",torque_enable"),
         r"run1.csv: line 3: column 'torque_enable' is 2; expected 0 \(torque off\) or 1 \(torque on\)"),
        (_rows("0,0,0,7.4", "0.005,0,0,0", "0.01,0,0,7.4", head=HEAD + ",voltage"),
         r"run1.csv: line 3: column 'voltage' is 0; expected a supply voltage > 0"),
        (_rows("0,0,0,7400", "0.005,0,0,7400", head=HEAD + ",voltage"), r"run1.csv: line 2: column 'voltage' is 7400"),
        (_rows("0,0,0,1", "0.005,0,0,", head=HEAD + ",torque_enable"),
         r"run1.csv: line 3: column 'torque_enable' is not a number \(''\)"),
    ],
)
def test_bad_logs(tmp_path: Path, csv_text: str, message: str) -> None:
    with pytest.raises(SysIDError, match=message):
        load_manifest(_manifest(tmp_path, csv_text))


def test_missing_file_and_unknown_motor(tmp_path: Path) -> None:
    path = _manifest(tmp_path, logs=[{"file": "nope.csv", "kp": 400}])
    with pytest.raises(SysIDError, match=r"manifest.json: logs\[0\] names 'nope.csv', but .*nope.csv does not exist"):
        load_manifest(path)
    path = _manifest(tmp_path, motor="XC999")
    with pytest.raises(SysIDError, match=r"manifest.json: unknown motor model 'XC999'"):
        load_manifest(path)
    path = _manifest(tmp_path, rig={"type": "pendulum", "mass": 0.49})
    with pytest.raises(SysIDError, match=r"manifest.json: rig 'pendulum' is missing 'length'"):
        load_manifest(path)


def test_torque_and_voltage_columns_and_manifest_voltage(tmp_path: Path) -> None:
    text = _rows("0,0,0,1,7.2", "0.005,0,0,1,7.4", "0.01,0,0,0,7.3", head=HEAD + ",torque_enable,voltage")
    run = load_manifest(_manifest(tmp_path, text)).runs[0]
    assert list(run.torque_enable) == [1, 1, 0] and list(run.voltage) == [7.2, 7.4, 7.3]
    run = load_manifest(_manifest(tmp_path, GOOD, voltage=7.4)).runs[0]  # manifest default fills a log without
    assert run.torque_enable is None and list(run.voltage) == [7.4, 7.4, 7.4]
    path = _manifest(tmp_path, GOOD, voltage=-1)
    with pytest.raises(SysIDError, match=r"manifest.json: voltage must be a supply voltage > 0 and <= 30 V, got -1"):
        load_manifest(path)


@pytest.mark.parametrize("name", ["../secret.csv", "/etc/passwd", "sub/../../secret.csv"])
def test_manifest_paths_must_stay_in_its_folder(tmp_path: Path, name: str) -> None:
    (tmp_path / "secret.csv").write_text("password-hunter2\n")
    folder = tmp_path / "runs"
    folder.mkdir()
    path = _manifest(folder, logs=[{"file": name, "kp": 400}])
    with pytest.raises(SysIDError, match=r"logs\[0\] names .* which is outside the manifest's folder") as err:
        load_manifest(path)
    assert "hunter2" not in str(err.value)
