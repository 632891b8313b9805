from pathlib import Path

import pytest
import yaml

from toddlerbot.errors import SpecError
from toddlerbot.robot.spec import DEFAULT_SPEC, load_spec


def test_total_mass_matches_reference(spec):
    assert spec.total_mass == pytest.approx(3.358, rel=0.01)


def test_thirty_motors_with_unique_bus_ids(spec):
    assert len(spec.motors) == 30
    assert sorted(m.id for m in spec.motors) == list(range(30))


def test_gripper_variant_adds_two_motors_and_grippers(gripper_spec):
    assert len(gripper_spec.motors) == 32
    names = {b.name for b in gripper_spec.bodies}
    assert "left_hand" not in names and "left_gripper" in names
    assert gripper_spec.total_mass == pytest.approx(3.487, rel=0.01)


def test_unknown_variant_is_rejected(spec):
    with pytest.raises(SpecError, match="unknown variant 'wings'"):
        spec.with_variant("wings")


def _write_modified(tmp_path: Path, edit) -> Path:
    data = yaml.safe_load(DEFAULT_SPEC.read_text())
    edit(data)
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _body(data, name):
    return next(b for b in data["bodies"] if b["name"] == name)


def test_missing_field_names_file_entry_and_field(tmp_path):
    path = _write_modified(tmp_path, lambda d: _body(d, "head").pop("mass"))
    with pytest.raises(SpecError) as err:
        load_spec(path)
    message = str(err.value)
    assert str(path) in message and "(head)" in message and "mass" in message and "missing required field" in message


def test_unknown_motor_model_is_rejected(tmp_path):
    def edit(d):
        d["motors"][4]["model"] = "XM999"

    with pytest.raises(SpecError, match=r"motor 'left_hip_pitch' \(id 4\): unknown motor model 'XM999'") as err:
        load_spec(_write_modified(tmp_path, edit))
    assert "robot.yaml" in str(err.value)


def test_inverted_joint_range_is_rejected(tmp_path):
    def edit(d):
        _body(d, "left_calf")["joint"]["range"] = [0.5, -0.5]

    with pytest.raises(SpecError, match=r"bodies\[\d+\] \(left_calf\)\.joint\.range: lower limit 0.5 is greater"):
        load_spec(_write_modified(tmp_path, edit))


def test_transmission_naming_missing_joint_is_rejected(tmp_path):
    def edit(d):
        next(t for t in d["transmissions"] if t["name"] == "left_knee")["driven"] = "left_knee_typo"

    with pytest.raises(SpecError, match="transmission 'left_knee': joint 'left_knee_typo' does not exist"):
        load_spec(_write_modified(tmp_path, edit))


def test_home_pose_outside_range_is_rejected(tmp_path):
    def edit(d):
        d["home"]["left_knee"] = 1.0

    with pytest.raises(SpecError, match=r"home: left_knee = 1.0 is outside its range"):
        load_spec(_write_modified(tmp_path, edit))


def test_unreadable_spec_names_the_file(tmp_path):
    with pytest.raises(SpecError, match=r"nope\.yaml: cannot read robot spec"):
        load_spec(tmp_path / "nope.yaml")
