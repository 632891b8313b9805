"""The motion-tracking environment `track` (`toddlerbot.rl.track_env`): its reference is the motion played on the
training model, episodes start on it, end where the robot leaves it, its rewards are whole on it and fall with the
error, it steps on both physics backends and trains through `rl train --env track --motion`."""

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("brax")

import jax
import jax.numpy as jnp

from cli_support import one_line_error, run_main
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.motions import full_pose, load_motion, motion_path
from toddlerbot.policies.rl_inference import RLPolicyFile
from toddlerbot.policies.track import TrackController
from toddlerbot.rl import config, track_rewards, train
from toddlerbot.rl.environments import environment_class
from toddlerbot.rl.export import export_run
from toddlerbot.rl.launch import TrainRequest, resume_plan
from toddlerbot.rl.model import training_model
from toddlerbot.rl.motion_reference import build_reference
from toddlerbot.rl.track_config import SMOKE_TRACK, TrackConfig
from toddlerbot.rl.track_env import TrackEnv
from toddlerbot.rl.track_rewards import TRACK_REWARDS, TrackQuantities
from toddlerbot.robot.description import RobotDescription

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src"
SQUAT = replace(SMOKE_TRACK, motion="squat", randomize=False, cpu_threads=1, hold_s=2.0)
"""The squat with its 2 s hold, no randomisation (the reference itself must be the perfect episode)."""
TRAIN_TRACK = """
import sys
from pathlib import Path
from toddlerbot.rl.launch import TrainRequest, new_run_plan
from toddlerbot.rl.train import train
plan = new_run_plan(Path(sys.argv[1]), TrainRequest(smoke=True, environment="track", motion="squat", backend="cpu"))
train(plan.run_dir, plan.env, plan.ppo, imitation_cfg=plan.imitation, max_epochs=1)
"""


@pytest.fixture(scope="module")
def cpu_env():
    return TrackEnv(replace(SQUAT, backend="cpu"))


def _uprightness(quat: np.ndarray) -> np.ndarray:
    """World-z component of the torso's z axis (1: upright)."""
    x, y = quat[..., 1], quat[..., 2]
    return 1 - 2 * (x * x + y * y)


def test_the_squat_reference_plays_the_motion_upright_then_holds_it(cpu_env):
    ref, description = cpu_env.reference, cpu_env.description
    motion = load_motion("squat", description)
    assert ref.motion_steps == 350 and ref.n_steps == 350 + 100 and ref.end_effectors.shape == (451, 4, 3)
    joints = [description.joint_names.index(j) for j in motion.joints]
    motor_pos = ref.qpos[:, cpu_env.addresses.motors.qpos]
    reached = description.transmission.motor_to_joint(motor_pos)[:, joints]
    wanted = np.stack([full_pose(motion, description, (i - 1) * ref.dt)[joints] for i in range(1, 451)])
    np.testing.assert_allclose(ref.motor_targets[:-1], [description.transmission.joint_to_motor(
        full_pose(motion, description, i * ref.dt)) for i in range(450)])
    assert np.sqrt(np.mean((reached[1:] - wanted) ** 2)) < 0.05  # rad: the joints follow the keyframes
    assert np.abs(reached[100] - wanted[99]).max() < 0.1  # t = 2 s, down in the squat: the loaded legs sag
    assert np.all(ref.motor_targets[350:] == ref.motor_targets[350])  # the final pose is held
    assert _uprightness(ref.torso_quat).min() > 0.98  # never more than 11 degrees from upright
    height = ref.torso_height
    assert 0.05 < height[0] - height[100] < 0.08 and abs(height[-1] - height[0]) < 0.005
    assert np.abs(ref.qpos[:, 0:2] - ref.qpos[0, 0:2]).max() < 0.04  # m: it squats where it stands
    feet, hands = ref.end_effectors[:, :2], ref.end_effectors[:, 2:]
    assert np.all(feet[:, :, 2] < -0.2) and np.all(hands[:, 0, 1] > 0.1) and np.all(hands[:, 1, 1] < -0.1)


def test_a_motion_that_starts_lying_starts_its_reference_on_the_floor_where_all_contacts_hold_it(tmp_path):
    """A motion whose first keyframe lies on the back (base pitch -90 degrees) starts its reference there; the
    whole-body contacts (track's default) hold the torso on the floor, walking's feet-and-hands set lets it sink."""
    lying = tmp_path / "lie.yaml"
    lying.write_text("joints: [neck_yaw]\nkeyframes:\n  - {t: 0, base: {pitch: -90}, neck_yaw: 0}\n"
                     "  - {t: 1, neck_yaw: 0}\n")
    description = RobotDescription.load()
    motion = load_motion(str(lying), description)
    heights = {}
    for contacts in ("all", "feet_hands"):
        cfg = TrackConfig(motion=str(lying), contacts=contacts)
        ref = build_reference(motion, description, training_model(description, cfg), cfg.ctrl_dt, cfg.n_substeps,
                              cfg.hold_s)
        assert abs(_uprightness(ref.torso_quat[0])) < 1e-6 and ref.n_steps == 150
        heights[contacts] = ref.torso_height
    assert 0.05 < heights["all"][0] < 0.15 and np.ptp(heights["all"]) < 0.005
    assert heights["feet_hands"].min() < 0.0  # the torso went through the floor


def test_reward_terms_are_whole_on_the_reference_and_fall_with_the_error(cpu_env):
    rows = cpu_env.rows
    exact = TrackQuantities(
        motor_pos=rows.motor_pos[120], ref_motor_pos=rows.motor_pos[120], motor_vel=rows.motor_vel[120],
        ref_motor_vel=rows.motor_vel[120], torso_quat=rows.torso_quat[120], ref_torso_quat=rows.torso_quat[120],
        torso_height=rows.torso_pos[120, 2], ref_torso_height=rows.torso_pos[120, 2],
        end_effectors=rows.end_effectors[120], ref_end_effectors=rows.end_effectors[120],
        action=jnp.full(30, 0.3), last_action=jnp.full(30, 0.3), alive=jnp.ones(()))
    cfg = cpu_env.cfg.reward
    whole = {name: float(value) for name, value in TRACK_REWARDS.total(exact, cfg, 0.02)[1].items()}
    assert whole == {"motor_pos": 1.0, "motor_vel": 1.0, "torso_orientation": 1.0, "torso_height": 1.0,
                     "end_effectors": 1.0, "action_rate": 0.0, "survival": 1.0}
    tilt = jnp.array([np.cos(0.1), np.sin(0.1), 0.0, 0.0])  # 0.2 rad about x, from upright
    off = exact._replace(motor_pos=exact.motor_pos + 0.1, motor_vel=exact.motor_vel + 0.5, torso_quat=tilt,
                         ref_torso_quat=jnp.array([1.0, 0, 0, 0]), torso_height=exact.torso_height + 0.05,
                         end_effectors=exact.end_effectors + jnp.array([0.05, 0, 0]), action=jnp.full(30, 0.4),
                         alive=jnp.zeros(()))
    dropped = {name: float(value) for name, value in TRACK_REWARDS.total(off, cfg, 0.02)[1].items()}
    expected = {"motor_pos": np.exp(-0.6), "motor_vel": np.exp(-0.375), "torso_orientation": np.exp(-50 * np.sin(0.1)
                ** 2), "torso_height": np.exp(-1.0), "end_effectors": np.exp(-0.4), "action_rate": -0.3,
                "survival": 0.0}
    assert dropped == pytest.approx(expected, rel=1e-4)
    assert track_rewards.MOTOR_POS_SIGMA == 2.0 and sum(TRACK_REWARDS.default_weights.values()) == pytest.approx(
        16.1)


def test_episodes_start_anywhere_on_the_reference_in_its_exact_state(cpu_env):
    states = jax.jit(jax.vmap(cpu_env.reset))(jax.random.split(jax.random.PRNGKey(7), 8))
    rows = np.asarray(states.info["row"])
    assert len(set(rows.tolist())) >= 6 and rows.min() >= 0 and rows.max() < cpu_env.reference.n_steps
    physics = jax.tree.map(np.asarray, states.pipeline_state)
    qpos, qvel, _ = physics.float64(np.arange(8))
    assert np.array_equal(qpos, cpu_env.reference.qpos[rows]) and np.array_equal(qvel, cpu_env.reference.qvel[rows])
    assert states.obs["state"].shape == (8, 3 * 96 + 1 + 3 * 30)
    phase = np.asarray(states.obs["state"][:, 3 * 96])
    np.testing.assert_allclose(phase, rows / cpu_env.reference.n_steps, rtol=1e-6)


def test_tracking_the_reference_keeps_every_term_whole_and_a_residual_costs(cpu_env):
    """Zero actions from a reset replay the reference on the CPU backend (float64; the env's float32 targets and
    model fields differ in the last bits): every tracking term stays within 1e-4 of 1, no episode ends."""
    reset, step = jax.jit(cpu_env.reset), jax.jit(cpu_env.step)
    state = reset(jax.random.PRNGKey(11))
    for _ in range(10):
        state = step(state, jnp.zeros(30))
        assert float(state.done) == 0.0
        for name in ("motor_pos", "motor_vel", "torso_orientation", "torso_height", "end_effectors", "survival"):
            assert abs(float(state.metrics[name]) - 1.0) < 1e-4, name
        assert float(state.metrics["motor_pos_error"]) < 1e-4 and float(state.metrics["end_effector_error"]) < 1e-5
    assert float(state.reward) == pytest.approx(16.0 * 0.02, abs=1e-5)
    pushed = state
    for _ in range(5):
        pushed = step(pushed, jnp.full(30, 0.8))  # 0.2 rad off on every motor
    assert float(pushed.metrics["motor_pos"]) < 0.5 and float(pushed.reward) < 16.0 * 0.02 - 0.1


def test_termination_fires_on_a_large_deviation_and_never_on_the_reference(cpu_env):
    frames, n = cpu_env._start_frames, cpu_env.reference.n_steps
    rows = jnp.arange(n + 1)
    assert not np.any(np.asarray(jax.vmap(cpu_env.terminated)(frames, rows)))
    frame = jax.tree.map(lambda x: x[200], frames)
    row = jnp.asarray(200)

    def ends(qpos) -> bool:
        return bool(cpu_env.terminated(frame._replace(qpos=qpos), row))

    qpos = frame.qpos
    turned = lambda angle: qpos.at[3:7].set(jnp.array([np.cos(angle / 2), 0, np.sin(angle / 2), 0]))  # noqa: E731
    assert ends(qpos.at[0].add(0.31)) and not ends(qpos.at[0].add(0.29))
    assert ends(qpos.at[2].add(-0.11)) and ends(qpos.at[2].add(0.11)) and not ends(qpos.at[2].add(-0.09))
    base = float(np.degrees(2 * np.arccos(float(qpos[3]))))
    assert base < 5 and ends(turned(1.0)) and not ends(turned(0.6))
    assert ends(qpos.at[2].set(jnp.nan))


def test_the_mjx_backend_starts_on_the_reference_and_tracks_it():
    env = TrackEnv(replace(SQUAT, backend="mjx"))
    state = jax.jit(env.reset)(jax.random.PRNGKey(11))
    row = int(state.info["row"])
    np.testing.assert_allclose(np.asarray(state.pipeline_state.qpos), env.reference.qpos[row], atol=1e-6)
    state = jax.jit(env.step)(state, jnp.zeros(30))
    assert float(state.done) == 0.0 and int(state.info["row"]) == row + 1
    for name in ("motor_pos", "motor_vel", "torso_orientation", "torso_height", "end_effectors"):
        assert abs(float(state.metrics[name]) - 1.0) < 1e-3, name


def test_track_is_registered_and_trains_one_smoke_epoch_on_the_cpu_backend(tmp_path):
    """`rl train --env track --motion squat --smoke` on the CPU backend: the run records the environment, its motion,
    the whole-body contacts and the tracking weights, reloads as a `TrackConfig`, keeps the motion on a resume, and
    its step reward stays within the table's bound (the weights' sum x the control period)."""
    assert environment_class("track") is TrackEnv and TrackEnv.default_config().contacts == "all"
    assert TrackEnv.recipe("cpu", smoke=True).imitation.iterations == 0
    run = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(SRC), "XLA_FLAGS": config.SMOKE_XLA_FLAGS}
    out = subprocess.run([sys.executable, "-c", TRAIN_TRACK, str(run)], env=env, capture_output=True, text=True,
                         timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    saved = json.loads((run / "config.json").read_text())["env"]
    assert saved["environment"] == "track" and saved["motion"] == "squat" and saved["contacts"] == "all"
    assert saved["reward"]["weights"] == TRACK_REWARDS.default_weights and saved["backend"] == "cpu"
    env_cfg, ppo_cfg = train.load_config(run)
    assert isinstance(env_cfg, TrackConfig) and env_cfg.motion == "squat" and ppo_cfg == config.SMOKE
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert len(records) == 1 and records[0]["env_steps"] == config.SMOKE.env_steps_per_update
    assert -0.5 < records[0]["step_reward"] <= 16.0 * env_cfg.ctrl_dt + 1e-6
    assert 0 <= records[0]["motor_pos_error"] < 0.3 and 0 <= records[0]["end_effector_error"] < 0.2
    assert {key for key, _ in TrackEnv.curves} <= set(records[0])  # its training_curve.png panels are recorded
    recorded = np.load(run / "action_space.npz")
    assert str(recorded["motion"]) == "squat" and recorded["motor_targets"].shape == (351 + 25, 30)
    assert (run / "reference.txt").read_text() == "motion squat\n"
    with pytest.raises(ToddlerbotError, match=r"^--motion: a resumed run keeps the settings it started with"):
        resume_plan(run, TrainRequest(motion="wave"))
    assert resume_plan(run, TrainRequest()).resume
    _the_export_plays_as_the_env_trained_it(run, tmp_path / "policy.npz", env_cfg)


def _the_export_plays_as_the_env_trained_it(run: Path, out: Path, env_cfg: TrackConfig) -> None:
    """`rl export` of a track run holds the motion (its tables and its file's text) and the `track` policy's
    controller, fed the env's sensor readings, builds the env's actor observations and commands its motor targets
    (the numpy network acting in both)."""
    export_run(run, out)
    policy = RLPolicyFile(out)
    recorded = np.load(run / "action_space.npz")
    assert policy.environment == "track" and policy.meta["runtime_policy"] == "track"
    assert policy.motion.name == "squat" and policy.motion.lookahead == env_cfg.lookahead
    np.testing.assert_array_equal(policy.motion.motor_targets, recorded["motor_targets"])
    assert policy.meta["motion_yaml"] == motion_path("squat").read_text()
    np.testing.assert_array_equal(policy.action_motor_index, np.arange(30))
    with pytest.raises(ToddlerbotError, match=r"a policy of the 'track' environment; walk-rl plays 'walk' policies "
                                              r"\(play it with --policy track\)"):
        policy.for_robot(policy.motor_names, 0.02, "walk", "walk-rl")
    noiseless = replace(env_cfg.obs, noise_motor_pos=0.0, noise_motor_vel=0.0, noise_gyro=0.0, noise_gravity=0.0)
    env = TrackEnv(replace(env_cfg, randomize=False, cpu_threads=1, obs=noiseless))
    step = jax.jit(env.step)
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    controller = TrackController(policy)
    controller.row = int(state.info["row"])
    for _ in range(4):
        sensors = jax.tree.map(np.asarray, state.info["sensors"])
        obs = controller.observe(sensors.motor_pos, sensors.motor_vel, sensors.gyro, sensors.imu_quat)
        np.testing.assert_allclose(obs, np.asarray(state.obs["state"]), atol=2e-6)
        action = policy.action(np.asarray(state.obs["state"]))
        row = controller.row
        np.testing.assert_allclose(controller.act(obs), recorded["motor_targets"][row] + 0.25 * action, atol=1e-5)
        state = step(state, jnp.asarray(action))
        assert int(state.info["row"]) == controller.row


def test_bad_motion_options_are_one_line(monkeypatch, capsys, tmp_path):
    def refused(*args) -> str:
        code, _, err = run_main(monkeypatch, capsys, "rl", "train", "--smoke", "--backend", "cpu", "--out",
                                tmp_path / "run", *args)
        assert not (tmp_path / "run").exists()
        return one_line_error(code, err)

    assert refused("--env", "track").startswith("error: --env track: needs --motion NAME_OR_FILE (built-in: ")
    assert refused("--env", "track", "--motion", "nope").startswith(
        "error: --motion: unknown motion 'nope': not a built-in (")
    assert refused("--motion", "squat") == "error: --motion squat: the 'walk' environment tracks no motion"
    bad = tmp_path / "bad.yaml"
    bad.write_text("joints: [left_knee]\nkeyframes:\n  - {t: 0, left_knee: 0}\n  - {t: 1, left_knee: 500}\n")
    assert refused("--env", "track", "--motion", bad) == (
        f"error: --motion: {bad}: keyframe 1: left_knee = 500 deg is out of range [-120.0, 0.0] deg")
    assert refused("--env", "track", "--motion", "squat", "--upper-body-pose", "0.5") == (
        "error: --upper-body-pose: upper-body pose 0.5, hand force 0.0: the track environment follows the motion's "
        "arms (expected 0)")
