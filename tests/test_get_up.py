"""Getting up after a fall: base poses in the motion format, how the torso lies from the IMU, the get-up motions
in the simulator, the `get-up` policy's choice of motion, and a small sample of fallen states (the benchmark's
`benchmarks/bench_get_up.py` measures 20 seeds per side)."""

import mujoco
import numpy as np
import pytest
import yaml

from toddlerbot.errors import ToddlerbotError
from toddlerbot.motion_editor.playback import simulate
from toddlerbot.policies import make_policy, policy_names
from toddlerbot.policies.get_up import shipped_trackers
from toddlerbot.policies.get_up_trials import LIMIT_S, STABLE_S, fallen_robot, get_up_trial
from toddlerbot.policies.lying import lying_on, up_in_torso, uprightness
from toddlerbot.policies.motions import (
    MotionError,
    builtin_motions,
    full_pose,
    load_motion,
    mirrored,
    motion_path,
    parse_motion,
)
from toddlerbot.policies.replay import ReplayPolicy
from toddlerbot.policies.rl_inference import RLPolicyFile
from toddlerbot.robot.fall import FALL_KP_FRACTION, FallGuard
from toddlerbot.robot.floor_pose import place_on_floor, tilt_quat
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

DT = 0.02


def _motion(frames, joints=("left_knee",)):
    return {"name": "m", "joints": list(joints), "keyframes": frames}


def test_a_keyframe_may_give_a_base_pose_and_the_old_motions_give_none(description):
    motion = parse_motion(_motion([{"t": 0, "base": {"pitch": -90}, "left_knee": -30},
                                   {"t": 1, "base": {"roll": 10, "pitch": 5, "z": 0.3}, "left_knee": -30},
                                   {"t": 2, "left_knee": -30}]), description, "m.yaml")
    assert motion.start_base.pitch == pytest.approx(-np.pi / 2) and motion.start_base.z is None
    assert motion.bases[1].roll == pytest.approx(np.deg2rad(10)) and motion.bases[1].z == 0.3
    assert motion.bases[2] is None
    for name in ("squat", "wave", "look_around"):
        assert load_motion(name, description).bases == ()  # unchanged: they start standing
    assert {"roll_from_back", "get_up_front"} <= set(builtin_motions())


@pytest.mark.parametrize(("base", "expected"), [
    ([0, 90], r"^m\.yaml: keyframe 0: base must be a mapping like \{roll: 0, pitch: -90\} \(deg; z in m\), "
              r"got \[0, 90\]$"),
    ({"yaw": 3}, r"^m\.yaml: keyframe 0: base\.yaw is not a base field; expected roll, pitch, z$"),
    ({"pitch": 200}, r"^m\.yaml: keyframe 0: base\.pitch must be a number of deg in \[-180, 180\], got 200$"),
    ({"roll": ".nan"}, r"^m\.yaml: keyframe 0: base\.roll must be a number of deg in \[-180, 180\], got '\.nan'$"),
    ({"z": -0.1}, r"^m\.yaml: keyframe 0: base\.z must be a number of m in \[0, 1\], got -0\.1$"),
    ({"z": True}, r"^m\.yaml: keyframe 0: base\.z must be a number of m in \[0, 1\], got True$"),
])
def test_a_bad_base_pose_is_one_line_naming_the_file_keyframe_and_field(description, base, expected):
    with pytest.raises(MotionError, match=expected):
        parse_motion(_motion([{"t": 0, "base": base, "left_knee": 0}, {"t": 1, "left_knee": 0}]), description,
                     "m.yaml")


def test_a_bad_motion_file_is_one_line(description, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(_motion([{"t": 0, "base": {"pitch": "flat"}, "left_knee": 0},
                                           {"t": 1, "left_knee": 0}])))
    with pytest.raises(ToddlerbotError) as info:
        load_motion(str(bad), description)
    assert "\n" not in str(info.value)
    assert str(info.value) == f"{bad}: keyframe 0: base.pitch must be a number of deg in [-180, 180], got 'flat'"


def test_mirroring_a_motion_twice_gives_it_back_and_flips_the_roll(description):
    roll = load_motion("roll_from_back", description)
    once, twice = mirrored(roll, description), mirrored(mirrored(roll, description), description)
    on_a_side = parse_motion(_motion([{"t": 0, "base": {"roll": 90}, "left_knee": -30}, {"t": 1, "left_knee": 0}]),
                             description, "m.yaml")
    assert mirrored(on_a_side, description).start_base.roll == pytest.approx(-np.pi / 2)
    waist = roll.at(1.0)[roll.joints.index("waist_yaw")]
    assert once.at(1.0)[once.joints.index("waist_yaw")] == pytest.approx(-waist) and abs(waist) > 1.0  # turns back
    for t in (0.0, 0.7, roll.duration):
        np.testing.assert_allclose(full_pose(twice, description, t), full_pose(roll, description, t), atol=1e-12)
    left, right = once.joints.index("right_hip_pitch"), roll.joints.index("left_hip_pitch")
    assert once.at(1.0)[left] == pytest.approx(-roll.at(1.0)[right])  # hip pitches mirror with opposite signs


@pytest.mark.parametrize(("roll", "pitch", "expected"), [
    (0, 0, "upright"), (0, -90, "back"), (0, 90, "front"), (90, 0, "right side"), (-90, 0, "left side"),
    (30, -90, "back"), (0, 20, "upright"), (0, 60, "front"),
])
def test_how_the_torso_lies_comes_from_the_imu_orientation(roll, pitch, expected):
    assert lying_on(tilt_quat(np.deg2rad(roll), np.deg2rad(pitch)), 0.9) == expected


def _lying_robot(description, roll_deg, pitch_deg):
    robot = MuJoCoRobot(description)
    robot.start_qpos = place_on_floor(robot.model, mujoco.MjData(robot.model), description.transmission,
                                      description.home_joint_pos, np.deg2rad(roll_deg), np.deg2rad(pitch_deg)).qpos
    robot.reset()
    return robot


@pytest.mark.parametrize(("roll", "pitch", "lying", "phase"), [
    (0, -90, "back", "roll"), (0, 90, "front", "get-up"), (90, 0, "right side", "roll"),
    (-90, 0, "left side", "roll"),
])
def test_the_policy_chooses_its_motion_from_the_imu(description, roll, pitch, lying, phase):
    robot = _lying_robot(description, roll, pitch)
    policy = make_policy("get-up", robot)
    obs = robot.observe()
    policy.reset(obs)
    for _ in range(round(0.6 / DT)):  # it waits until the torso is still, then reads how it lies
        action = policy.act(obs, np.zeros(3))
        obs = robot.step(action.motor_targets)
    status = policy.status
    assert status.lying == (lying,) and status.phase == phase and status.attempts == 1
    assert not policy.done and not policy.succeeded
    assert status.to_dict()["lying"] == [lying] and lying in status.describe()


def test_a_robot_already_standing_is_checked_and_handed_back_at_home(description):
    robot = MuJoCoRobot(description)
    policy = make_policy("get-up", robot)
    obs = robot.reset()
    policy.reset(obs)
    for _ in range(round(1.2 / DT)):
        action = policy.act(obs, np.zeros(3))
        obs = robot.step(action.motor_targets)
    assert policy.done and policy.succeeded and policy.attempts == 0
    np.testing.assert_allclose(action.joint_targets, description.home_joint_pos)
    assert "get-up" in policy_names()


def test_the_front_motion_stands_the_robot_up_from_lying_on_its_front(description):
    playback = simulate(description, load_motion("get_up_front", description))
    assert playback.from_lying and playback.error is None
    assert playback.upright and playback.final_uprightness >= 0.95
    assert playback.describe().startswith("stood up")


def test_the_back_motion_rolls_the_robot_from_its_back_onto_its_front(description):
    motion = load_motion("roll_from_back", description)
    robot = _lying_robot(description, 0, -90)
    policy = ReplayPolicy(robot, motion)
    obs = robot.observe()
    policy.reset(obs)
    for _ in range(round((motion.duration + 0.5) / DT)):
        obs = robot.step(policy.act(obs, np.zeros(3)).motor_targets)
    up = up_in_torso(obs.imu_quat)
    assert lying_on(obs.imu_quat, 0.9) == "front" and np.degrees(abs(np.arctan2(up[1], up[0]))) > 160
    # at home, where get_up_front starts, but for the arms the floor presses (a shoulder roll 0.22 rad off)
    np.testing.assert_allclose(obs.joint_pos, description.home_joint_pos, atol=0.3)


def test_the_shipped_trackers_were_trained_on_the_get_up_motions_as_they_are_now():
    """A motion re-paced after its tracker was trained would be played at the tracker's old pace: retrain, then
    `rl export --ship` (docs/rl.md "Trackers of `get_up_front`")."""
    trackers = shipped_trackers()
    assert set(trackers) == {"get_up_front", "roll_from_back"}
    for name, path in trackers.items():
        assert RLPolicyFile(path).meta["motion_yaml"] == motion_path(name).read_text(), name


@pytest.mark.parametrize(("seed", "side", "lying"), [(0, "front", ("front",)), (1, "back", ("back", "front")),
                                                     (2, "right", ("right side", "front"))])
def test_a_robot_knocked_over_while_walking_stands_within_ten_seconds_and_walks_on(description, seed, side, lying):
    fallen = fallen_robot(description, seed, side)
    assert fallen is not None and uprightness(fallen.robot.observe().imu_quat) < 0.3
    trial = get_up_trial(fallen)
    assert trial.stood and trial.time_to_stand < LIMIT_S - STABLE_S and trial.attempts == 1
    assert trial.lying == lying and trial.longest_over_stall < 1.0 and trial.walked_on


def test_a_robot_that_turns_while_lying_keeps_its_gains_and_a_fall_from_upright_lowers_them():
    kp = np.full(3, 800.0)
    upright, lying = tilt_quat(0.0, 0.0), tilt_quat(0.0, np.pi / 2)
    turning, still = np.array([3.0, 0.0, 0.0]), np.zeros(3)
    guard = FallGuard(DT)
    for _ in range(5):  # started lying (a get-up): pushing itself up turns the torso, which is no fall
        guard.update(lying, turning)
        assert guard.gains(kp, kp) is kp
    guard.update(upright, still)  # stood up: armed again
    guard.update(lying, turning)  # and fell
    np.testing.assert_allclose(guard.gains(kp, kp), FALL_KP_FRACTION * kp)


def test_a_run_handed_to_get_up_after_a_kick_walks_on_standing(description):
    """What `sim run --on-fall get-up` does: the run loop hands the fallen robot to the policy and walks on."""
    from toddlerbot.runtime.robustness import DirectedKick
    from toddlerbot.runtime.runner import run_policy

    robot = MuJoCoRobot(description)
    get_up = make_policy("get-up", robot)
    command = np.array([0.1, 0.0, 0.0])
    result = run_policy(robot, make_policy("walk-rl", robot), lambda t: command, 15.0,
                        observers=[DirectedKick(robot, 1.5, 0.0, 2.0)], recovery=get_up, record_log=False)
    assert (result.falls, result.recoveries, result.completed) == (1, 1, True)
    assert get_up.succeeded and get_up.attempts == 1 and get_up.status.lying == ("front",)
    assert robot.torso_height() > 0.9 * robot.standing_height and robot.torso_uprightness() > 0.9


def test_a_robot_that_stays_down_is_tried_three_times_then_given_up_holding_still(description):
    robot = _lying_robot(description, 0, -90)
    robot.set_gains(np.zeros(description.n_motors), description.default_kd)  # limp: no motion can move it
    policy = make_policy("get-up", robot)
    obs = robot.observe()
    policy.reset(obs)
    limp = np.zeros(description.n_motors)
    for _ in range(round(40.0 / DT)):
        action = policy.act(obs, np.zeros(3))
        obs = robot.step(action.motor_targets, limp)
        if policy.done:
            break
    assert policy.done and not policy.succeeded and policy.attempts == 3
    assert policy.status.lying == ("back", "back", "back") and policy.status.describe().startswith("get-up: gave up")
    np.testing.assert_allclose(policy.act(obs, np.zeros(3)).joint_targets, obs.joint_pos, atol=0.05)
