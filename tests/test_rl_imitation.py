"""DAgger's teacher: walk-zmp started with each episode is in phase with the tabulated reference, and its labels
are its own leg targets expressed as residual actions (slow: JIT-compiles the CPU environment's step)."""

from dataclasses import replace

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("brax")
jnp = jax.numpy

from toddlerbot.rl.config import CommandConfig, EnvConfig  # noqa: E402
from toddlerbot.rl.imitation import TeacherBatch, teacher_action, teacher_gain_scales  # noqa: E402
from toddlerbot.rl.walk_env import WalkEnv  # noqa: E402
from toddlerbot.rl.wrappers import wrap_for_training  # noqa: E402
from toddlerbot.robot.description import RobotDescription  # noqa: E402

pytestmark = pytest.mark.slow


def test_labels_are_the_teachers_targets_and_the_teacher_walks_in_phase_with_the_reference():
    description = RobotDescription.load()
    # a 2 x 2 x 2 grid is quick to tabulate; its vx axis is (0, 0.15) m/s
    command_cfg = replace(CommandConfig(grid=(2, 2, 2)), stand_prob=0.0, turn_prob=0.0, axis_prob=1.0)
    env = WalkEnv(EnvConfig(backend="cpu", randomize=False, command=command_cfg), description)
    n, steps = 2, 75
    train_env = wrap_for_training(env, 1000)
    state = jax.jit(train_env.reset)(jax.random.split(jax.random.PRNGKey(0), n))
    command = np.array([0.1, 0.0, 0.0])
    state.info["command"] = jnp.tile(jnp.asarray(command, jnp.float32), (n, 1))
    step = jax.jit(train_env.step)
    teacher = TeacherBatch.build(description, n)
    leg, scale = env.leg_index, env.cfg.obs.action_scale
    in_phase, in_bounds, start_x = [], [], np.asarray(state.pipeline_state.qpos[:, 0])
    for _ in range(steps):
        info = jax.device_get({k: state.info[k] for k in ("time", "command", "sensors")})
        s = info["sensors"]
        targets = teacher.act(info["time"] < 1e-6, info["time"], info["command"], s.motor_pos, s.imu_quat, s.gyro)
        ref_leg, ref_contact = jax.vmap(env.reference_at)(jnp.asarray(info["command"]), jnp.asarray(info["time"]))
        ref_leg = np.asarray(ref_leg)
        label = teacher_action(targets, ref_leg, leg, scale)
        inside = np.abs(label) < 1.0
        # the label's leg targets are the teacher's (where it is not clipped to the action bounds)
        np.testing.assert_allclose((ref_leg + scale * label)[inside], targets[:, leg][inside], atol=1e-9)
        if info["time"][0] > 0.5:  # after walk-zmp's standing start (the reference is a steady-state cycle)
            in_bounds.append(inside)
            planned = np.array([p.last_reference.contact for p in teacher.policies])
            in_phase.append(np.all(planned == (np.asarray(ref_contact) > 0.5), axis=1))
        state = step(state, jnp.asarray(label, jnp.float32))
    assert np.mean(in_phase) > 0.95, np.mean(in_phase)
    # once in step with the reference, the teacher's leg targets lie within the residual's reach
    assert np.mean(in_bounds) > 0.95, np.mean(in_bounds)
    assert not np.any(np.asarray(state.done))
    walked = np.asarray(state.pipeline_state.qpos[:, 0]) - start_x
    assert np.all(walked > 0.05), walked  # 1.5 s at 0.1 m/s after a 0.4 s standing start


def test_teacher_gains_are_walk_zmps_schedule():
    description = RobotDescription.load()
    stance, swing = teacher_gain_scales(description)
    legs = description.groups["leg"]
    others = np.setdiff1d(np.arange(description.n_motors), legs)
    np.testing.assert_allclose(stance[legs], 2.0)  # WalkZMPPolicy's leg_kp_scale
    np.testing.assert_allclose(stance[others], 1.0)
    assert set(np.unique(swing)) == {0.0, 3.0}  # swing_kp_scale on the swinging leg's motors
    assert not np.any((swing[0] > 0) & (swing[1] > 0))
