"""The walking environment: per-env domain randomisation, observations, and physics that keep the robot up.

The physics test JIT-compiles one environment step (slow on CPU: about a minute), so it is marked ``slow``.
"""

from dataclasses import replace

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("mujoco.mjx")
jnp = jax.numpy

from toddlerbot.rl.config import smoke_env_config  # noqa: E402
from toddlerbot.rl.reference import standing_table  # noqa: E402
from toddlerbot.rl.walk_env import WalkEnv  # noqa: E402
from toddlerbot.robot.description import RobotDescription  # noqa: E402


@pytest.fixture(scope="module")
def env():
    cfg = smoke_env_config()
    description = RobotDescription.load()
    return WalkEnv(cfg, description, reference=standing_table(description, cfg.command, period=0.6),
                   gain_scales=(np.ones(30), np.zeros((2, 30))))


@pytest.fixture(scope="module")
def states(env):
    return jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 4))


def test_each_env_gets_its_own_randomisation_draw(env, states):
    dr = states.info["dr"]
    cfg = env.cfg.randomization
    for name in ("floor_friction", "torso_added_mass", "obs_noise_level"):
        values = np.asarray(getattr(dr, name))
        assert len(np.unique(values)) == 4, name
    lo, hi = cfg.floor_friction
    assert np.all((np.asarray(dr.floor_friction) >= lo) & (np.asarray(dr.floor_friction) <= hi))
    kp = np.asarray(dr.kp_scale)  # (envs, motors): different per env and per motor
    assert kp.shape == (4, 30) and not np.allclose(kp[0], kp[1]) and np.ptp(kp[0]) > 0
    # the draw reaches the env's physics model
    model = env.model_fields(jax.tree.map(lambda x: x[1], dr))
    assert float(model["geom_friction"][env.floor_geom, 0]) == pytest.approx(float(dr.floor_friction[1]))
    torso_mass = float(model["body_mass"][env.torso_body])
    nominal = float(env.mj_model.body_mass[env.torso_body])
    expected = nominal * float(dr.mass_scale[1, env.torso_body]) + float(dr.torso_added_mass[1])
    assert torso_mass == pytest.approx(expected, rel=1e-5)


def test_the_critic_sees_the_path_error_only_where_the_path_term_is_weighted(env, states):
    cfg = env.cfg
    weighted = replace(cfg, reward=replace(cfg.reward, weights={**cfg.reward.weights, "path_xy": 5.0}))
    env_with_path = WalkEnv(weighted, env.description, reference=env.reference, gain_scales=env.gain_scales)
    state = jax.jit(env_with_path.reset)(jax.random.PRNGKey(0))
    assert cfg.reward.weights["path_xy"] == 0
    assert state.obs["privileged_state"].shape[-1] == states.obs["privileged_state"].shape[-1] + 2
    assert state.obs["state"].shape[-1] == states.obs["state"].shape[-1]  # the actor's observation is unchanged


def test_observations_have_history_and_privileged_extras(env, states):
    frame = env.frame_size
    actor = np.asarray(states.obs["state"])
    assert actor.shape == (4, env.cfg.obs.history * frame)
    np.testing.assert_array_equal(actor[:, :frame], actor[:, frame:2 * frame])  # history filled with frame 0
    assert states.obs["privileged_state"].shape[1] > actor.shape[1]
    # command and phase sit at the start of each frame: phase (sin 0, cos 0) = (0, 1) at reset
    np.testing.assert_allclose(actor[:, :2], np.tile([0.0, 1.0], (4, 1)), atol=1e-6)
    np.testing.assert_allclose(actor[:, 2:5], np.asarray(states.info["command"]))


@pytest.mark.slow
def test_zero_actions_keep_the_robot_standing_and_rewarded(env, states):
    step = jax.jit(jax.vmap(env.step))
    state = states
    for _ in range(25):  # 0.5 s with the home pose held by the actuator model
        state = step(state, jnp.zeros((4, 12)))
    z = np.asarray(state.pipeline_state.qpos[:, 2])  # the CPU backend's state: float32 part of the float64
    assert np.all(z > 0.3), z
    assert not np.any(np.asarray(state.done))
    assert np.all(np.asarray(state.metrics["survival"]) == 1.0)
    np.testing.assert_array_equal(np.asarray(state.info["last_contact"]), 1.0)  # both feet on the floor
    assert np.all(np.asarray(state.reward) > 0)
    # standing, the averaged velocity is ~0, and the tracking term scores it against each env's command
    avg, command = np.asarray(state.info["avg_vel"]), np.asarray(state.info["command"])
    assert np.all(np.abs(avg) < 0.03)
    sigma = env.cfg.reward.velocity_sigma
    expected = np.exp(-sigma * np.sum((avg[:, :2] - command[:, :2]) ** 2, axis=1))
    np.testing.assert_allclose(np.asarray(state.metrics["lin_vel_xy"]), expected, rtol=1e-4)
    # standing still against a command, the path error grows backwards along it: -command x memory x (1 - e^-t/m)
    memory = env.cfg.reward.path_memory_s
    behind = -command[:, :2] * memory * (1 - np.exp(-0.5 / memory))
    np.testing.assert_allclose(np.asarray(state.info["path_error"]), behind, atol=0.01)
    assert np.max(np.abs(behind)) > 0.02  # the commands are large enough for the check to mean something
    assert np.all(np.asarray(state.info["time"]) == pytest.approx(0.5))


def test_an_imu_age_band_draws_each_episode_s_age_and_leaves_every_other_draw_as_before():
    from toddlerbot.rl import randomization
    from toddlerbot.rl.config import RandomizationConfig

    keys = jax.random.split(jax.random.PRNGKey(3), 6)
    fresh = [randomization.sample(k, RandomizationConfig(), 20, 10, 30) for k in keys]
    aged = [randomization.sample(k, RandomizationConfig(imu_age_s=(0.005, 0.015)), 20, 10, 30) for k in keys]
    ages = np.array([float(d.imu_age) for d in aged])
    assert np.all((ages >= 0.005) & (ages <= 0.015)) and len(np.unique(ages)) == 6
    assert all(float(d.imu_age) == 0.0 for d in fresh)  # the default: fresh readings
    for before, after in zip(fresh, aged, strict=True):  # runs from before the age existed draw as they did
        for name in ("floor_friction", "kp_scale", "obs_noise_level", "action_delay"):
            np.testing.assert_array_equal(getattr(before, name), getattr(after, name))


def test_an_aged_imu_reading_lies_between_the_previous_control_step_s_and_this_one_s():
    from toddlerbot.rl.observations import Sensors, aged_imu

    def sensors(gyro, quat):
        return Sensors(jnp.zeros(3), jnp.zeros(3), jnp.asarray(gyro, jnp.float32), jnp.asarray(quat, jnp.float32))

    half_turn = np.array([np.cos(0.05), 0.0, 0.0, np.sin(0.05)])  # 0.1 rad of yaw
    previous, now = sensors([0.2, 0.0, -1.0], [1.0, 0.0, 0.0, 0.0]), sensors([0.4, 0.0, 1.0], half_turn)
    np.testing.assert_allclose(aged_imu(previous, now, 0.0).gyro, now.gyro)
    np.testing.assert_allclose(aged_imu(previous, now, 1.0).gyro, previous.gyro)
    middle = aged_imu(previous, now, 0.5)
    np.testing.assert_allclose(middle.gyro, [0.3, 0.0, 0.0], atol=1e-6)
    assert np.linalg.norm(middle.imu_quat) == pytest.approx(1.0, abs=1e-6)
    assert 2 * np.arctan2(float(middle.imu_quat[3]), float(middle.imu_quat[0])) == pytest.approx(0.05, abs=1e-4)
    # the same orientation written with the other sign is the same reading, not a flip through the origin
    flipped = aged_imu(sensors([0.2, 0.0, -1.0], [-1.0, 0.0, 0.0, 0.0]), now, 0.5)
    np.testing.assert_allclose(flipped.imu_quat, middle.imu_quat, atol=1e-6)
    np.testing.assert_array_equal(middle.motor_pos, now.motor_pos)  # the motors are read fresh
