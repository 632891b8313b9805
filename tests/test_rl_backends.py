"""The environment's two physics backends: classic MuJoCo on threads (CPU) steps exactly like the simulator on the
training model, and the MJX backend gives the same observations and rewards (one JAX definition above both).

Each test JIT-compiles an environment step (tens of seconds on the shared 2-core CPU; MJX about a minute)."""

from dataclasses import replace

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("mujoco.mjx")
jnp = jax.numpy

from toddlerbot.policies.motions import load_motion  # noqa: E402
from toddlerbot.rl.config import smoke_env_config  # noqa: E402
from toddlerbot.rl.model import training_model  # noqa: E402
from toddlerbot.rl.reference import standing_table  # noqa: E402
from toddlerbot.rl.walk_env import WalkEnv  # noqa: E402
from toddlerbot.robot.description import RobotDescription  # noqa: E402
from toddlerbot.sim.mujoco_robot import MuJoCoRobot  # noqa: E402

pytestmark = pytest.mark.slow

N_MOTORS = 30


@pytest.fixture(scope="module")
def description():
    return RobotDescription.load()


def _env(description, **changes):
    cfg = replace(smoke_env_config(), **changes)
    gains = (np.ones(N_MOTORS), np.zeros((2, N_MOTORS)))
    return WalkEnv(cfg, description, reference=standing_table(description, cfg.command, 0.6), gain_scales=gains)


def _squat_targets(description, seconds):
    motion = load_motion("squat", description)
    joint_index = [description.joint_names.index(j) for j in motion.joints]
    targets = []
    for k in range(round(seconds / 0.02)):
        q = np.array(description.home_joint_pos)
        q[joint_index] = motion.at((k + 1) * 0.02)
        targets.append(description.transmission.joint_to_motor(q))
    return np.array(targets)


def test_cpu_backend_steps_like_the_simulator_on_the_training_model(description):
    env = _env(description, backend="cpu", randomize=False)
    targets = _squat_targets(description, 2.0)
    physics = env.physics
    actuators = env.actuators
    step = jax.jit(lambda s, t: physics.step(s, t, None, actuators))
    state = physics.home_state
    qpos = []
    for target in targets:
        state, _ = step(state, jnp.asarray(target, jnp.float32))
        qpos.append(jax.tree.map(np.asarray, state).float64(...)[0])
    qpos = np.array(qpos)

    robot = MuJoCoRobot(description, model=training_model(description, env.cfg))
    robot._params = type(actuators)(*(np.asarray(a, np.float64) for a in actuators))  # the env's float32 values
    expected = []
    for target in targets:
        robot.step(np.asarray(target, np.float32).astype(float))  # the env's targets are float32
        expected.append(robot.data.qpos.copy())
    expected = np.array(expected)
    heights = expected[:, 2]
    assert heights.max() - heights.min() > 0.04  # the squat really moves
    # the same float64 simulation: the env's state carries MuJoCo's doubles exactly
    np.testing.assert_array_equal(qpos, expected)


def test_a_pull_on_the_hands_moves_the_robot_its_way(description):
    env = _env(description, backend="cpu", randomize=False)
    physics, actuators = env.physics, env.actuators
    home = jnp.asarray(env.home_motor_pos)
    step = jax.jit(lambda s, f: physics.step(s, home, None, actuators, f))
    velocity = {}
    for pull in (0.0, -3.0, 3.0):
        state, _ = step(physics.home_state, jnp.array([pull, 0.0, 0.0]))
        velocity[pull] = float(jax.tree.map(np.asarray, state).float64(...)[1][0])
        np.testing.assert_array_equal(physics._datas[0].xfrc_applied[env.addresses.hand_bodies, :3],
                                      [[pull, 0.0, 0.0]] * 2)
    # 6 N on the 3.4 kg robot for one 20 ms control step: about 0.035 m/s for the whole robot, the torso's share
    # the same way as the pull
    print("torso vx after one step with -6 / 0 / +6 N on the hands:", velocity)
    assert velocity[-3.0] < velocity[0.0] - 0.005 and velocity[3.0] > velocity[0.0] + 0.005


def test_mjx_and_cpu_backends_give_the_same_observations_and_rewards(description):
    steps, n = 10, 3
    results = {}
    for backend in ("cpu", "mjx"):
        smoke = smoke_env_config()  # both backends pull the hands of each env its own way
        env = _env(description, backend=backend, randomization=replace(smoke.randomization, hand_force=2.0))
        reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
        state = reset(jax.random.split(jax.random.PRNGKey(3), n))
        actions = jnp.asarray(np.random.default_rng(0).uniform(-0.3, 0.3, (steps, n, env.action_size)), jnp.float32)
        obs, reward = [], []
        for a in actions:
            state = step(state, a)
            obs.append(np.asarray(state.obs["privileged_state"]))
            reward.append(np.asarray(state.reward))
        results[backend] = np.array(obs), np.array(reward), state
        if backend == "cpu":  # each env's randomised model reached its MjModel
            friction = np.asarray(state.info["dr"].floor_friction)
            models = env.physics._models[:n]
            np.testing.assert_allclose([m.geom_friction[env.floor_geom, 0] for m in models], friction, rtol=1e-6)
            torso = [m.body_mass[env.torso_body] for m in models]
            assert len(set(np.round(torso, 6))) == n
    (obs_c, rew_c, _), (obs_m, rew_m, _) = results["cpu"], results["mjx"]
    print(f"MJX vs CPU over {steps} steps: observations {np.abs(obs_c - obs_m).max():.1e}, "
          f"rewards {np.abs(rew_c - rew_m).max():.1e}")
    # float32 MJX against float64 MuJoCo, the same randomisation, commands and pushes: after one step the
    # states still agree (measured: rewards 1e-4 apart), then the two simulations drift apart (6 % in 10 steps)
    np.testing.assert_allclose(rew_m[0], rew_c[0], atol=2e-3)
    np.testing.assert_allclose(obs_m[0], obs_c[0], atol=2e-2)
    np.testing.assert_allclose(rew_m, rew_c, rtol=0.15)
