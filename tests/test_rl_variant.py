"""Training a walking policy for a spec variant (the 32-motor gripper robot) with randomised upper-body poses."""

from dataclasses import replace

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("mujoco.mjx")
jnp = jax.numpy

from toddlerbot.errors import ToddlerbotError  # noqa: E402
from toddlerbot.rl.config import RandomizationConfig, smoke_env_config  # noqa: E402
from toddlerbot.rl.randomization import hand_force, upper_body_offsets  # noqa: E402
from toddlerbot.rl.reference import standing_table  # noqa: E402
from toddlerbot.rl.walk_env import WalkEnv  # noqa: E402
from toddlerbot.robot.description import RobotDescription  # noqa: E402
from toddlerbot.robot.upper_body import upper_body_mask  # noqa: E402

FRACTION = 0.5


@pytest.fixture(scope="module")
def gripper():
    return RobotDescription.load(variant="gripper")


def _env(description, fraction=FRACTION, randomize=True, resample_s=5.0, pull=0.0):
    cfg = smoke_env_config()
    cfg = replace(cfg, variant=description.spec.variant, randomize=randomize,
                  randomization=replace(cfg.randomization, upper_body_pose=fraction, hand_force=pull),
                  command=replace(cfg.command, resample_s=resample_s))
    return WalkEnv(cfg, description, reference=standing_table(description, cfg.command, period=0.6),
                   gain_scales=(np.ones(description.n_motors), np.zeros((2, description.n_motors))))


def _bounds(description, fraction):
    home = np.asarray(description.home_motor_pos)
    lo, hi = np.asarray(description.motor_range).T
    return home - fraction * (home - lo), home + fraction * (hi - home)


def test_upper_body_is_the_arms_grippers_and_neck(gripper):
    mask = upper_body_mask(gripper)
    names = {gripper.motor_names[i] for i in np.flatnonzero(mask)}
    assert names == set(gripper.group_names("arm") + gripper.group_names("gripper") + gripper.group_names("neck"))
    assert len(names) == 18 and not any(n in names for n in gripper.group_names("leg") + gripper.group_names("waist"))


def test_offsets_fill_the_fraction_of_each_range_and_nothing_else(gripper):
    mask = upper_body_mask(gripper)
    home = jnp.asarray(gripper.home_motor_pos, dtype=jnp.float32)
    motor_range = jnp.asarray(gripper.motor_range, dtype=jnp.float32)
    draws = np.asarray(jax.vmap(lambda k: upper_body_offsets(k, FRACTION, home, motor_range, jnp.asarray(mask)))(
        jax.random.split(jax.random.PRNGKey(0), 400)))
    targets = np.asarray(home) + draws
    lo, hi = _bounds(gripper, FRACTION)
    assert np.all(draws[:, ~mask] == 0.0)
    assert np.all((targets >= lo - 1e-6) & (targets <= hi + 1e-6))
    # uniform over the whole band: 400 draws reach within 5 % of both ends on every upper-body motor
    width = (hi - lo)[mask]
    assert np.all(targets[:, mask].min(axis=0) < lo[mask] + 0.05 * width)
    assert np.all(targets[:, mask].max(axis=0) > hi[mask] - 0.05 * width)
    with pytest.raises(ValueError, match=r"upper_body_pose 1\.5"):
        RandomizationConfig(upper_body_pose=1.5)


def test_the_variant_env_has_its_motors_and_one_pose_per_env(gripper):
    env = _env(gripper)
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 4))
    assert env.n_motors == 32 and env.action_size == 12
    assert states.obs["state"].shape == (4, env.cfg.obs.history * env.cfg.obs.frame_size(32, 12))
    pose = np.asarray(states.info["upper_body"])
    mask = upper_body_mask(gripper)
    assert np.all(pose[:, ~mask] == 0.0) and np.all(np.abs(pose[:, mask]).max(axis=0) > 0)
    assert len({tuple(p) for p in pose.round(6)}) == 4
    # without randomisation (evaluation) the upper body holds home
    calm = jax.jit(jax.vmap(_env(gripper, randomize=False).reset))(jax.random.split(jax.random.PRNGKey(0), 2))
    assert np.all(np.asarray(calm.info["upper_body"]) == 0.0)
    with pytest.raises(ValueError, match="variant 'gripper' differs from the config's None"):
        WalkEnv(smoke_env_config(), gripper)


def test_hand_pulls_fill_their_band_and_come_with_each_command(gripper):
    pulls = np.asarray(jax.vmap(lambda k: hand_force(k, 2.0))(jax.random.split(jax.random.PRNGKey(1), 400)))
    horizontal = np.linalg.norm(pulls[:, :2], axis=1)
    assert horizontal.max() <= 2.0 + 1e-6 and horizontal.max() > 1.9 and horizontal.min() < 0.1
    assert np.abs(pulls[:, 2]).max() <= 1.0 + 1e-6 and pulls[:, 2].min() < -0.9 and pulls[:, 2].max() > 0.9
    heading = np.arctan2(pulls[:, 1], pulls[:, 0])  # every direction: each quadrant gets about a quarter
    assert np.all(np.histogram(heading, bins=4, range=(-np.pi, np.pi))[0] > 60)
    env = _env(gripper, fraction=0.0, pull=2.0)
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 4))
    drawn = np.asarray(states.info["hand_force"])
    assert drawn.shape == (4, 3) and len({tuple(p) for p in drawn.round(6)}) == 4
    assert np.all(np.linalg.norm(drawn[:, :2], axis=1) <= 2.0 + 1e-6)
    calm = jax.jit(_env(gripper, randomize=False, pull=2.0).reset)(jax.random.PRNGKey(0))
    assert np.all(np.asarray(calm.info["hand_force"]) == 0.0)  # evaluation: nothing pulls
    for bad in (-1.0, float("nan"), float("inf"), 1e308, 30.5):  # at most about the robot's weight
        with pytest.raises(ValueError, match=r"hand_force .*: expected a force in \[0, 30\] N"):
            RandomizationConfig(hand_force=bad)


@pytest.mark.slow
def test_the_arms_follow_the_drawn_pose_until_the_next_command(gripper):
    env = _env(gripper, resample_s=0.4, pull=0.5)  # a new command, pose and pull every 20 control steps
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    step = jax.jit(env.step)
    drawn, pull = np.asarray(state.info["upper_body"]), np.asarray(state.info["hand_force"])
    arm = np.asarray(gripper.groups["arm"])
    home = np.asarray(gripper.home_motor_pos)
    for _ in range(19):
        state = step(state, jnp.zeros(12))
    np.testing.assert_array_equal(np.asarray(state.info["upper_body"]), drawn)
    np.testing.assert_array_equal(np.asarray(state.info["hand_force"]), pull)
    reached = np.asarray(state.pipeline_state.qpos)[env.motor_qadr][arm] - home[arm]
    # after 0.38 s every arm motor has covered most of its way to the drawn pose, the robot still up
    assert np.all(np.abs(reached - drawn[arm]) < 0.3 * np.abs(drawn[arm]) + 0.05), (reached, drawn[arm])
    assert not bool(state.done)
    state = step(state, jnp.zeros(12))
    assert not np.array_equal(np.asarray(state.info["upper_body"]), drawn)
    assert not np.array_equal(np.asarray(state.info["hand_force"]), pull)


def test_rl_train_checks_the_variant_options_before_compiling(tmp_path):
    from toddlerbot.rl.launch import TrainRequest, new_run_plan, resume_plan

    plan = new_run_plan(tmp_path / "run", TrainRequest(smoke=True, variant="gripper", upper_body_pose=0.4))
    assert plan.env.variant == "gripper" and plan.env.randomization.upper_body_pose == 0.4
    with pytest.raises(ToddlerbotError, match=r"unknown variant 'nope'; expected one of \['gripper'\]"):
        new_run_plan(tmp_path / "bad", TrainRequest(smoke=True, variant="nope"))
    with pytest.raises(ToddlerbotError, match=r"--upper-body-pose: upper_body_pose 2\.0"):
        new_run_plan(tmp_path / "bad", TrainRequest(smoke=True, upper_body_pose=2.0))
    plan = new_run_plan(tmp_path / "pull", TrainRequest(smoke=True, variant="gripper", hand_force=1.5))
    assert plan.env.randomization.hand_force == 1.5
    with pytest.raises(ToddlerbotError, match=r"--hand-force: hand_force -1\.0: expected a force in \[0, 30\] N"):
        new_run_plan(tmp_path / "bad", TrainRequest(smoke=True, hand_force=-1.0))
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "config.json").write_text("{}")
    for request, option in ((TrainRequest(variant="gripper"), "--variant"),
                            (TrainRequest(hand_force=1.0), "--hand-force")):
        with pytest.raises(ToddlerbotError, match=f"^{option}: a resumed run keeps"):
            resume_plan(tmp_path / "old", request)
