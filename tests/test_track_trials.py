"""Trials of a motion on the CPU simulator (`toddlerbot.rl.track_trials`): open-loop replay against an exported
tracking policy, judged against the motion's reference."""

import json

import numpy as np
import pytest

pytest.importorskip("jax")

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.get_up import GetUpPolicy
from toddlerbot.policies.get_up_trials import fallen_robot, get_up_trial
from toddlerbot.policies.rl_inference import ACTION_DISTRIBUTION
from toddlerbot.policies.track import TrackPolicy
from toddlerbot.policies.track_observation import MotionTargets
from toddlerbot.policies.walk_rl import SHIPPED_WEIGHTS
from toddlerbot.rl.track_config import TrackConfig
from toddlerbot.rl.track_env import TrackEnv
from toddlerbot.rl.track_trials import CONDITIONS, MotionTrials
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

NOMINAL = CONDITIONS[0]


@pytest.fixture(scope="module")
def trials():
    return MotionTrials(RobotDescription.load(), "get_up_front")


def constant_policy(path, trials: MotionTrials, action: float):
    """An exported tracking policy of ``trials``' motion whose action is ``action`` on every motor, always."""
    description, cfg = trials.description, trials.cfg
    n = description.n_motors
    width = MotionTargets("", trials.reference.motor_targets, 1, cfg.lookahead).actor_width(cfg.obs.history, n)
    arrays = {"distribution": np.array(ACTION_DISTRIBUTION), "action_std": np.full(n, 0.1, np.float32),
              "layer0_kernel": np.zeros((width, 8), np.float32), "layer0_bias": np.zeros(8, np.float32),
              "layer1_kernel": np.zeros((8, n), np.float32), "layer1_bias": np.full(n, action, np.float32),
              "obs_mean": np.zeros(width, np.float32), "obs_std": np.ones(width, np.float32)}
    meta = {"ctrl_dt": cfg.ctrl_dt, "environment": "track", "runtime_policy": "track"}
    return TrackEnv.write_export(path, arrays, cfg, meta, description, trials.reference.arrays())


def test_a_zero_residual_tracker_plays_what_replay_plays_and_the_front_get_up_completes(trials, tmp_path):
    """The `track` policy commands the reference's targets step for step (zero actions: the open-loop motion), so
    the two players' trials agree (to the replay's own rounding of its clock, amplified by the contacts); the
    nominal robot lying on its front gets up, within 0.01 rad of the reference's joints and 0.03 rad of its torso's
    tilt on average, its heading within 0.1 rad at the end (0.006, 0.019 and 0.075 measured: the 5.9 s motion is
    quicker than the 8.6 s one before it, and two simulations of it part a little more)."""
    zero = constant_policy(tmp_path / "zero.npz", trials, 0.0)
    replay = trials.trial("replay", NOMINAL, 0)
    tracked = trials.trial("track", NOMINAL, 0, zero)
    assert replay.completed and replay.stood and replay.left_at is None
    assert replay.motor_rmse < 0.01 and replay.tilt_error < 0.03 and abs(replay.heading_error) < 0.1
    assert tracked.completed and abs(tracked.motor_rmse - replay.motor_rmse) < 1e-3
    assert abs(tracked.tilt_error - replay.tilt_error) < 5e-3


def test_a_tracker_that_leaves_the_reference_does_not_complete(trials, tmp_path):
    """+0.25 rad on every motor throughout: the robot leaves the reference (and the trial says when)."""
    bent = constant_policy(tmp_path / "bent.npz", trials, 1.0)
    trial = trials.trial("track", NOMINAL, 0, bent)
    assert not trial.completed and trial.left_at is not None and trial.motor_rmse > 0.1


def test_the_track_policy_refuses_a_walking_policy_and_plays_its_motion_to_the_end(trials, tmp_path):
    zero = constant_policy(tmp_path / "zero.npz", trials, 0.0)
    robot = MuJoCoRobot(trials.description)
    policy = TrackPolicy(robot, zero)
    policy.reset(robot.observe())
    for _ in range(trials.reference.n_steps):
        assert not policy.done
        policy.act(robot.observe(), np.zeros(3))
    assert policy.done and policy.status.to_dict() == {"motion": "get_up_front", "step": trials.reference.n_steps,
                                                       "steps": trials.reference.n_steps, "done": True}
    assert json.loads(str(np.load(zero)["meta"]))["motion"] == "get_up_front"


def test_get_up_plays_the_front_motion_with_its_tracker_and_refuses_a_tracker_of_another_motion(trials, tmp_path):
    """A robot knocked onto its front while walking stands up with the front motion played by a (zero-residual)
    tracker, on one attempt; a tracker named for a motion it was not trained on is one line."""
    zero = constant_policy(tmp_path / "zero.npz", trials, 0.0)
    fallen = fallen_robot(trials.description, 0, "front")
    trial = get_up_trial(fallen, {"get_up_front": zero})
    assert trial.stood and trial.attempts == 1 and trial.lying == ("front",) and trial.longest_over_stall < 1.0
    with pytest.raises(ToddlerbotError, match=r"zero.npz: a tracker for 'roll_from_back' must be a tracking policy of "
                                              r"that motion, one of get_up_front, roll_from_back$"):
        GetUpPolicy(MuJoCoRobot(trials.description), {"roll_from_back": zero})


def test_a_tracker_of_a_built_in_motion_ships_beside_the_walking_policies(tmp_path):
    """`rl export --ship` of a track run writes ``weights/track_<motion>.npz`` (where `get-up` finds it); a motion
    file or a variant ships nothing."""
    cfg = TrackConfig(motion="get_up_front")
    assert TrackEnv.shipped_export(cfg) == SHIPPED_WEIGHTS / "track_get_up_front.npz"
    with pytest.raises(ToddlerbotError, match=r"^--ship: only trackers of a built-in motion on the packaged robot "
                                              r"ship \(this run: motion '/x/my.yaml', variant None\)$"):
        TrackEnv.shipped_export(TrackConfig(motion="/x/my.yaml"))


def test_a_roll_completes_where_its_reference_ends_lying_and_a_get_up_where_it_stands(trials):
    """A motion that does not end upright (the back's roll onto the front) is judged by where it ends, not by standing:
    replayed on the nominal robot it completes without standing; the front get-up must stand to complete."""
    roll = MotionTrials(trials.description, "roll_from_back")
    assert trials.ends_standing and not roll.ends_standing
    replay = roll.trial("replay", NOMINAL, 0)
    assert replay.completed and not replay.stood and replay.left_at is None
