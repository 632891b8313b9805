"""The motion editor's parts without a browser: keyframe edits and their YAML, the mirror map from the joint axes,
balance (CoM, support polygon), playback in the simulator, save-path rules and the command's one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from toddlerbot.motion_editor.balance import PoseModel, convex_hull, signed_margin
from toddlerbot.motion_editor.keyframes import Keyframes
from toddlerbot.motion_editor.mirror import MirrorMap
from toddlerbot.motion_editor.playback import simulate
from toddlerbot.policies.motions import MOTIONS_DIR, MotionError, load_motion, parse_motion

DEG = np.pi / 180


@pytest.fixture(scope="module")
def mirror(description):
    return MirrorMap.of(description)


def test_keyframe_edits_keep_a_valid_motion_and_its_timing(description):
    doc = Keyframes.from_motion(load_motion("wave", description), description)
    assert len(doc) == 9 and doc.times[-1] == pytest.approx(5.0)
    assert doc.insert_after(1) == 2  # a copy of keyframe 1, as long as keyframe 1's transition (1 s)
    np.testing.assert_array_equal(doc.poses[2], doc.poses[1])
    assert doc.times[-1] == pytest.approx(6.0)
    doc.set_duration(2, 0.25)
    assert doc.times[2] == pytest.approx(1.25)
    first, second = doc.poses[0].copy(), doc.poses[1].copy()
    assert doc.move(0, +1) == 1 and doc.move(0, -1) == 0  # poses swap, durations stay in place
    np.testing.assert_array_equal(doc.poses[0], second)
    np.testing.assert_array_equal(doc.poses[1], first)
    np.testing.assert_allclose(doc.times[:3], [0, 1, 1.25])
    assert doc.delete(2) == 2 and len(doc) == 9
    with pytest.raises(MotionError, match="first keyframe"):
        doc.set_duration(0, 1.0)
    with pytest.raises(MotionError, match=r"duration 0 s: expected 0\.05-60 s"):
        doc.set_duration(1, 0.0)
    # a joint is clamped to its range (right_shoulder_roll: -90..20 deg)
    assert doc.set_joint(1, "right_shoulder_roll", 50 * DEG) == pytest.approx(20 * DEG)
    two = Keyframes.new(description)
    with pytest.raises(MotionError, match="at least two keyframes"):
        two.delete(0)


def test_saved_yaml_lists_moved_joints_and_reads_back_as_the_same_motion(description):
    doc = Keyframes.new(description, name="lean")
    doc.set_joint(1, "left_knee", -45.004 * DEG)
    doc.set_joint(1, "neck_yaw", 150 * DEG)  # clamped to the spec's 2.61799 rad = 149.9998 deg
    text = doc.to_yaml()  # rounded to 0.01 deg, inward at the range's end
    assert "joints: [neck_yaw, left_knee]" in text and "{t: 1.0, neck_yaw: 149.99, left_knee: -45.0}" in text
    import yaml

    motion = parse_motion(yaml.safe_load(text), description, "lean.yaml")
    assert motion.joints == ("neck_yaw", "left_knee") and motion.duration == 1.0
    np.testing.assert_allclose(np.rad2deg(motion.poses[1]), [149.99, -45.0])
    home = np.rad2deg(description.home_joint_pos[description.joint_names.index("left_knee")])
    assert motion.poses[0][1] == pytest.approx(np.deg2rad(round(home, 2)))


def test_mirror_signs_come_from_the_joint_axes_and_the_home_pose_is_symmetric(description, mirror):
    home = np.array(description.home_joint_pos)
    np.testing.assert_allclose(mirror.swapped(home), home, atol=1e-12)
    sign = dict(zip(description.joint_names, mirror.sign))
    assert sign["left_hip_pitch"] == -1 and sign["left_shoulder_roll"] == 1 and sign["neck_pitch"] == 1
    assert sign["neck_yaw"] == -1 and sign["waist_roll"] == -1
    pose = home.copy()
    names = list(description.joint_names)
    pose[names.index("left_shoulder_pitch")] = 40 * DEG
    pose[names.index("neck_yaw")] = 30 * DEG
    copied = mirror.copied(pose, "left")
    assert np.rad2deg(copied[names.index("right_shoulder_pitch")]) == pytest.approx(-40)
    assert np.rad2deg(copied[names.index("neck_yaw")]) == pytest.approx(30)  # the centre stays
    swapped = mirror.swapped(pose)
    assert np.rad2deg(swapped[names.index("neck_yaw")]) == pytest.approx(-30)
    assert np.rad2deg(swapped[names.index("left_shoulder_pitch")]) == pytest.approx(10)  # right home -10, mirrored
    assert mirror.follow(pose, "left_shoulder_pitch") == ("right_shoulder_pitch", pytest.approx(-40 * DEG))
    assert mirror.follow(pose, "neck_yaw") is None


def test_support_polygon_and_com_of_the_home_pose(description):
    poses = PoseModel(description)
    data = poses.pose(np.array(description.home_joint_pos))
    balance = poses.static_balance()
    assert len(balance.polygon) == 4  # both soles flat: the hull of their outer corners
    span = balance.polygon.max(axis=0) - balance.polygon.min(axis=0)
    assert span[0] == pytest.approx(0.12, abs=0.01) and span[1] == pytest.approx(0.116, abs=0.01)
    assert balance.supported and 0.04 < balance.margin < 0.06
    assert 0.28 < balance.com[2] < 0.32
    assert min(data.geom_xpos[:, 2][1:]) > -0.05  # standing on the floor, not in it
    # one foot lifted 5 cm: the polygon shrinks to the other sole
    names = list(description.joint_names)
    pose = np.array(description.home_joint_pos)
    pose[names.index("left_hip_pitch")] += 40 * DEG
    pose[names.index("left_knee")] -= 80 * DEG
    poses.pose(pose)
    single = poses.static_balance()
    assert len(single.polygon) == 4 and np.ptp(single.polygon[:, 1]) < 0.05


def test_top_view_marks_the_com_green_inside_and_red_outside(description):
    from toddlerbot.motion_editor.balance import Balance
    from toddlerbot.motion_editor.topview import SIZE_PX, top_view

    poses = PoseModel(description)
    data = poses.pose(np.array(description.home_joint_pos))
    balance = poses.static_balance()
    image = top_view(balance, poses.soles(data))
    assert image.shape == (SIZE_PX, SIZE_PX, 3)
    green = np.all(image == (40, 170, 70), axis=-1)
    rows, _ = np.nonzero(green[60:160, 60:160])  # the CoM dot sits mid-picture, the polygon around it
    assert green.sum() > 300 and abs(np.median(rows) + 60 - SIZE_PX / 2) < 30
    outside = Balance(balance.com + np.array([0.1, 0, 0]), balance.polygon, -0.04)
    assert np.all(top_view(outside, poses.soles(data)) == (220, 50, 40), axis=-1).sum() > 300


def test_hull_and_margin_are_exact_on_a_square():
    square = convex_hull(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [1, 0.5]]))
    assert len(square) == 4
    assert signed_margin(np.array([0.5, 0.25]), square) == pytest.approx(0.25)
    assert signed_margin(np.array([2.0, 0.5]), square) == pytest.approx(-1.0)
    assert signed_margin(np.array([0.5, 0.5]), convex_hull(np.array([[0, 0], [1, 1]]))) == -np.inf


def test_play_reports_upright_for_wave_and_a_fall_for_a_deep_lean(description):
    wave = simulate(description, load_motion("wave", description))
    assert wave.upright and wave.max_tilt_deg < 6 and len(wave.times) == 251
    assert all(b.supported for b in wave.balance[::25])
    doc = Keyframes.new(description, name="lean")
    for joint in ("left_hip_pitch", "right_hip_pitch"):
        k = description.joint_names.index(joint)
        doc.set_joint(1, joint, description.home_joint_pos[k] + (80 if joint.startswith("left") else -80) * DEG)
    doc.set_duration(1, 0.5)
    lean = simulate(description, doc.to_motion("lean"))
    assert not lean.upright and lean.fall_time < 1.5 and lean.describe().startswith("FELL at")


def test_save_path_rules(tmp_path):
    from toddlerbot.motion_editor.app import check_save_path

    with pytest.raises(MotionError, match="name a file"):
        check_save_path("  ")
    with pytest.raises(MotionError, match="inside the installed toddlerbot package"):
        check_save_path(str(MOTIONS_DIR / "wave.yaml"))
    with pytest.raises(MotionError, match=r"ending in \.yaml"):
        check_save_path(str(tmp_path / "wave.txt"))
    assert check_save_path(str(tmp_path / "w.yaml")) == tmp_path / "w.yaml"


@pytest.mark.parametrize("args,expected", [
    (["BAD"], "bad.yaml: keyframe 1: left_knee = 500 deg is out of range [-120.0, 0.0] deg"),
    (["wave", "--out", "copy.txt"], "copy.txt: expected a file name ending in .yaml"),
    (["wave", "--out", str(MOTIONS_DIR / "mine.yaml")], "inside the installed toddlerbot package"),
    (["wave", "--host", "8.8.8.8"], "--host 8.8.8.8: cannot listen there"),
    (["no_such_motion"], "unknown motion 'no_such_motion'"),
], ids=["bad_file", "not_yaml", "into_package", "foreign_host", "unknown"])
def test_bad_input_is_one_line_exit_2(args, expected, tmp_path, capsys, monkeypatch):
    from toddlerbot.cli.main import main

    bad = tmp_path / "bad.yaml"
    bad.write_text("joints: [left_knee]\nkeyframes:\n  - {t: 0, left_knee: -30}\n  - {t: 1, left_knee: 500}\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.argv", ["toddlerbot", "motion", "edit", *[str(bad) if a == "BAD" else a for a in args]])
    with pytest.raises(SystemExit) as exit_info:
        main()
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err, err


def test_page_actions_without_a_browser(description, tmp_path):
    """The page's handlers on a served editor (no client): mirror, reorder, the status line's one-line errors."""
    pytest.importorskip("viser")
    from toddlerbot.motion_editor.app import limb_groups, open_editor

    groups = limb_groups(description)
    assert list(groups) == ["Neck", "Waist", "Left arm", "Right arm", "Left leg", "Right leg"]
    assert len(groups["Left leg"]) == 6 and sum(map(len, groups.values())) == 30
    editor = open_editor(description, Keyframes.from_motion(load_motion("wave", description), description), None,
                         "127.0.0.1", 0)
    try:
        names = list(description.joint_names)
        editor.save("")
        assert editor.status.content.startswith("**error:** name a file to save to")
        editor._edit("Later")  # keyframe 0's pose moves to 1
        assert editor.current == 1 and editor.sliders["right_shoulder_roll"].value == -15
        editor._mirror("Left → right")  # the left arm's home pose onto the right: wave's raise is undone
        pose = editor.doc.poses[1]
        assert np.rad2deg(pose[names.index("right_shoulder_roll")]) == pytest.approx(-15, abs=1e-3)
        assert editor.sliders["right_shoulder_yaw"].value == pytest.approx(60)
        editor.duration.value = 0.01  # below 0.05 s: refused, the motion keeps its timing
        assert "duration 0.01 s: expected 0.05-60 s" in editor.status.content and editor.doc.times[1] == 1.0
        path = editor.save(str(tmp_path / "w.yaml"))
        assert path is not None and "9 keyframes, 5.00 s" in editor.status.content
    finally:
        editor.server.stop()


def test_a_keyframe_lying_on_the_back_is_drawn_on_the_floor_saved_and_moved_with_its_pose(description):
    from toddlerbot.policies.motions import BasePose

    doc = Keyframes.new(description, name="lie")
    doc.set_base(0, BasePose(pitch=-90 * DEG))
    data = PoseModel(description).pose(doc.poses[0], doc.bases[0])
    torso = data.body(description.handles.torso)
    assert torso.xmat[6] == pytest.approx(1.0)  # the torso's x axis (its chest) points up
    assert 0.08 < torso.xpos[2] < 0.12  # resting on its back: the torso box's back face on the floor
    text = doc.to_yaml()
    assert "{t: 0.0, base: {roll: 0.0, pitch: -90.0}," in text and "base" not in text.splitlines()[-1]
    import yaml

    assert parse_motion(yaml.safe_load(text), description, "lie.yaml").start_base.pitch == pytest.approx(-90 * DEG)
    assert doc.move(0, +1) == 1 and doc.bases == [None, BasePose(pitch=-90 * DEG)]  # the base goes with the pose
    assert doc.insert_after(1) == 2 and doc.bases[2] == doc.bases[1]
    assert doc.delete(0) == 0 and len(doc.bases) == 2


def test_play_starts_a_motion_lying_down_and_says_whether_it_ended_standing(description):
    from toddlerbot.policies.motions import BasePose

    doc = Keyframes.new(description, name="lie")
    doc.set_base(0, BasePose(pitch=90 * DEG))  # lying on its front, holding home: it stays down
    playback = simulate(description, doc.to_motion("lie"))
    assert playback.from_lying and not playback.upright and abs(playback.final_uprightness) < 0.2
    assert playback.times[-1] == pytest.approx(1.02)  # to the motion's end, not stopped by the fall detector
    assert playback.describe().startswith("ended down (uprightness")
