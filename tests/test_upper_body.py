"""Random upper-body poses and walking with the upper body held at one (`robot.upper_body`,
`policies.held_upper_body`, the ``posed`` robustness conditions)."""

import numpy as np
import pytest

from toddlerbot.policies.held_upper_body import HeldUpperBody
from toddlerbot.policies.stand import StandPolicy
from toddlerbot.policies.walk_rl import WalkRLPolicy
from toddlerbot.policies.walk_zmp import WalkZMPPolicy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.upper_body import random_upper_body_pose, upper_body_mask
from toddlerbot.runtime.robustness import conditions, run_trial
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


@pytest.fixture(scope="module")
def gripper():
    return RobotDescription.load(variant="gripper")


def test_random_poses_fill_the_band_of_the_upper_body_only(gripper):
    home = np.asarray(gripper.home_motor_pos)
    lo, hi = np.asarray(gripper.motor_range).T
    mask = upper_body_mask(gripper)
    poses = np.array([random_upper_body_pose(gripper, 0.3, np.random.default_rng(s)) for s in range(300)])
    assert np.all(poses[:, ~mask] == home[~mask])
    band_lo, band_hi = home - 0.3 * (home - lo), home + 0.3 * (hi - home)
    assert np.all((poses >= band_lo - 1e-9) & (poses <= band_hi + 1e-9))
    width = (band_hi - band_lo)[mask]
    assert np.all(poses[:, mask].min(axis=0) < band_lo[mask] + 0.05 * width)
    assert np.all(poses[:, mask].max(axis=0) > band_hi[mask] - 0.05 * width)
    np.testing.assert_array_equal(random_upper_body_pose(gripper, 0.3, np.random.default_rng(7)),
                                  random_upper_body_pose(gripper, 0.3, np.random.default_rng(7)))
    with pytest.raises(ValueError, match=r"upper-body pose fraction 1\.2: expected a fraction of the range in"):
        random_upper_body_pose(gripper, 1.2, np.random.default_rng(0))


def test_the_held_policy_replaces_only_the_upper_body_targets(gripper):
    robot = MuJoCoRobot(gripper)
    obs = robot.reset()
    inner = StandPolicy(robot)
    pose = random_upper_body_pose(gripper, 0.5, np.random.default_rng(1))
    held = HeldUpperBody(inner, pose)
    held.reset(obs)
    inner_action = inner.act(obs, np.zeros(3))
    action = held.act(obs, np.zeros(3))
    mask = upper_body_mask(gripper)
    np.testing.assert_array_equal(action.motor_targets[mask], pose[mask])
    np.testing.assert_array_equal(action.motor_targets[~mask], inner_action.motor_targets[~mask])
    np.testing.assert_allclose(action.joint_targets, gripper.transmission.motor_to_joint(action.motor_targets))
    with pytest.raises(ValueError, match=r"upper-body pose: expected 32 finite motor angles, got shape \(30,\)"):
        HeldUpperBody(inner, np.zeros(30))


@pytest.mark.slow
@pytest.mark.parametrize("policy", [WalkZMPPolicy, WalkRLPolicy], ids=["walk-zmp", "walk-rl"])
def test_walking_policies_walk_with_the_arms_held_at_random_poses(gripper, policy):
    """Two commands x two seeds, 4 s, the upper body held 0.3 of the way to its limits from the start (walk-rl: the
    gripper variant's shipped policy, trained with such poses, run symmetric); the full table (both fractions, the
    whole reach, 9 seeds: walk-zmp 3/90 falls, walk-rl 4/90, 2 of them turning at 0.4 rad/s) is
    `benchmarks/bench_walk_robustness.py --variant gripper`. A rate: at most one fall in the four."""
    posed = next(c for c in conditions() if c.name == "posed 0.3")
    trials = [run_trial(gripper, policy, command, posed, seed, 4.0)
              for command in ((0.075, 0.0, 0.0), (0.0, 0.0, 0.4)) for seed in (0, 1)]
    assert len([t for t in trials if t.fell]) <= 1, [(t.command, t.seed, t.fall_time) for t in trials if t.fell]
    assert trials[0].displacement[0] > 0.15 and trials[1].displacement[0] > 0.15  # 0.3 m planned
