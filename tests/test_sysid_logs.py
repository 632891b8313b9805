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


@pytest.mark.parametrize(
    ("csv_text", "message"),
    [
        ("time,goal_position,position\n0,0,0\n0.01,0,0\n0.005,0,0\n", r"run1.csv: time is not strictly increasing"),
        ("time,goal_position,position\n0,0,0\n0.01,nan,0\n", r"run1.csv: column 'goal_position' has NaN"),
        ("time,position\n0,0\n0.01,0\n", r"run1.csv: missing column\(s\) goal_position"),
        ("time,goal_position,position\n0,0,0\n0.01,abc,0\n", r"run1.csv: line 3: column 'goal_position' is not a"),
        ("time,goal_position,position\n0,0,0\n", r"run1.csv: needs at least 2 samples"),
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
