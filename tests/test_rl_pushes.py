"""Pushes in training: each kick's speed is drawn from a band (`push_velocity_min`..`push_velocity`), set by
`rl train --push-velocity LO HI`, and the time to the next push from another (`push_interval_s`, `--push-interval`)."""

from dataclasses import replace

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("mujoco.mjx")
jnp = jax.numpy

from toddlerbot.errors import ToddlerbotError  # noqa: E402
from toddlerbot.rl.config import RandomizationConfig, smoke_env_config  # noqa: E402
from toddlerbot.rl.reference import standing_table  # noqa: E402
from toddlerbot.rl.walk_env import WalkEnv  # noqa: E402
from toddlerbot.robot.description import RobotDescription  # noqa: E402


def _kicks(band: tuple[float, float], randomize: bool = True, n: int = 300,
           interval: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kicks (n, 2) m/s, torso velocity change (n, 2) m/s, time to the next push (n,) s) of a due push for n
    keys (``interval``: the push interval band, None: the configuration's)."""
    description = RobotDescription.load()
    cfg = smoke_env_config()
    cfg = replace(cfg, randomize=randomize, randomization=replace(
        cfg.randomization, push_velocity_min=band[0], push_velocity=band[1],
        push_interval_s=interval or cfg.randomization.push_interval_s))
    env = WalkEnv(cfg, description, reference=standing_table(description, cfg.command, period=0.6),
                  gain_scales=(np.ones(description.n_motors), np.zeros((2, description.n_motors))))
    state = env.reset(jax.random.PRNGKey(0))
    info = dict(state.info, push_timer=jnp.zeros(()))

    def kick(key):
        data, pushed = env._push(state.pipeline_state, dict(info), key)
        return pushed["push"], data.qvel[:2] - state.pipeline_state.qvel[:2], pushed["push_timer"]

    return tuple(np.asarray(a) for a in jax.vmap(kick)(jax.random.split(jax.random.PRNGKey(1), n)))


def test_push_speeds_fill_the_band_in_every_direction_and_move_the_torso_by_them():
    kicks, moved, _ = _kicks((0.2, 0.35))
    speed = np.linalg.norm(kicks, axis=1)
    assert speed.min() >= 0.2 - 1e-6 and speed.max() <= 0.35 + 1e-6
    assert speed.min() < 0.21 and speed.max() > 0.34  # 300 draws reach both ends of the band
    angle = np.arctan2(kicks[:, 1], kicks[:, 0])
    assert np.histogram(angle, bins=4, range=(-np.pi, np.pi))[0].min() > 50  # every quadrant
    np.testing.assert_allclose(moved, kicks, atol=1e-6)


def test_no_push_without_randomisation_and_the_default_band_starts_at_zero():
    kicks, moved, _ = _kicks((0.2, 0.35), randomize=False, n=8)
    assert np.all(kicks == 0.0) and np.all(moved == 0.0)
    default = RandomizationConfig()
    assert (default.push_velocity_min, default.push_velocity) == (0.0, 0.3)


def test_the_time_to_the_next_push_fills_the_interval_band():
    _, _, timer = _kicks((0.2, 0.35), interval=(1.5, 3.0))
    assert timer.min() >= 1.5 and timer.max() <= 3.0
    assert timer.min() < 1.56 and timer.max() > 2.94 and abs(timer.mean() - 2.25) < 0.08  # uniform over the band
    assert RandomizationConfig().push_interval_s == (2.0, 5.0)


@pytest.mark.parametrize("interval", [(3.0, 1.5), (0.0, 2.0), (1.0, float("inf")), (1.0, 1e9)])
def test_a_bad_push_interval_is_refused_by_the_config_and_by_rl_train_in_one_line(tmp_path, interval):
    from toddlerbot.rl.launch import TrainRequest, new_run_plan

    with pytest.raises(ValueError, match=r"push interval .*: expected 0 < shortest <= longest <= 600 s"):
        RandomizationConfig(push_interval_s=interval)
    with pytest.raises(ToddlerbotError, match=r"^--push-interval: push interval .*: expected 0 < shortest"):
        new_run_plan(tmp_path / "bad", TrainRequest(smoke=True, push_interval=interval))
    assert not (tmp_path / "bad").exists()  # nothing written for a refused request
    plan = new_run_plan(tmp_path / "run", TrainRequest(smoke=True, push_interval=(1.5, 3.0)))
    assert plan.env.randomization.push_interval_s == (1.5, 3.0)


@pytest.mark.parametrize("band", [(0.4, 0.3), (-0.1, 0.3), (0.1, float("inf")), (0.1, 1e9), (0.1, 3.1)])
def test_a_bad_band_is_refused_naming_it(band):
    with pytest.raises(ValueError, match=r"push velocities .*: expected 0 <= smallest <= largest <= 3 m/s"):
        RandomizationConfig(push_velocity_min=band[0], push_velocity=band[1])


def test_rl_train_sets_the_band_and_refuses_a_bad_one_in_one_line(tmp_path):
    from toddlerbot.rl.launch import TrainRequest, new_run_plan

    plan = new_run_plan(tmp_path / "run", TrainRequest(smoke=True, push_velocity=(0.15, 0.35)))
    assert (plan.env.randomization.push_velocity_min, plan.env.randomization.push_velocity) == (0.15, 0.35)
    with pytest.raises(ToddlerbotError, match=r"--push-velocity: push velocities 0\.5\.\.0\.3: expected"):
        new_run_plan(tmp_path / "bad", TrainRequest(smoke=True, push_velocity=(0.5, 0.3)))


def _run_at(tmp_path, steps: int):
    """A run directory whose config is a smoke run's with pushes of 0.15-0.35 m/s and whose last checkpoint is at
    ``steps`` PPO env steps (checkpoint files empty: only their names are read here)."""
    from toddlerbot.rl import config, train
    from toddlerbot.rl.launch import TrainRequest, new_run_plan

    run = tmp_path / "run"
    plan = new_run_plan(run, TrainRequest(smoke=True, push_velocity=(0.15, 0.35)))
    run.mkdir(exist_ok=True)
    train.save_config(run, plan.env, replace(plan.ppo, num_timesteps=1000), config.SMOKE_IMITATION)
    (run / "checkpoints").mkdir()
    for n in (steps // 2, steps):
        (run / "checkpoints" / f"step_{n:012d}.msgpack").touch()
    return run


def test_a_resumed_run_goes_on_with_a_new_band_from_its_last_checkpoint_as_a_recorded_stage(tmp_path):
    from toddlerbot.rl import train
    from toddlerbot.rl.launch import TrainRequest, resume_plan

    run = _run_at(tmp_path, 400)
    assert train.training_stages(run) == [{"from_env_steps": 0, "push_velocity": [0.15, 0.35],
                                           "push_interval_s": [2.0, 5.0], "imu_age_s": [0.0, 0.0],
                                           "terrain": "flat", "terrain_seed": 0, "terrain_start": 0.25,
                                           "desired_kl": 0.01, "num_timesteps": 1000}]
    plan = resume_plan(run, TrainRequest(push_velocity=(0.25, 0.4), timesteps=2000))
    assert plan.resume and plan.env is None  # the run reads its (new) configuration itself
    env_cfg, ppo_cfg = train.load_config(run)
    assert (env_cfg.randomization.push_velocity_min, env_cfg.randomization.push_velocity) == (0.25, 0.4)
    assert ppo_cfg.num_timesteps == 2000
    stages = train.training_stages(run)
    assert [(s["from_env_steps"], s["push_velocity"], s["num_timesteps"]) for s in stages] == [
        (0, [0.15, 0.35], 1000), (400, [0.25, 0.4], 2000)]
    # which bands trained a checkpoint: the one at the boundary had seen only the first
    assert [s["from_env_steps"] for s in train.stages_until(stages, 400)] == [0]
    assert [s["from_env_steps"] for s in train.stages_until(stages, 440)] == [0, 400]
    # a resume without options keeps the stages; one from the same checkpoint replaces the stage it starts
    resume_plan(run, TrainRequest())
    assert train.training_stages(run) == stages
    resume_plan(run, TrainRequest(push_velocity=(0.3, 0.3)))
    assert [(s["from_env_steps"], s["push_velocity"]) for s in train.training_stages(run)] == [
        (0, [0.15, 0.35]), (400, [0.3, 0.3])]


def test_a_resumed_run_goes_on_with_pushes_more_often_as_a_recorded_stage(tmp_path):
    from toddlerbot.rl import train
    from toddlerbot.rl.launch import TrainRequest, resume_plan

    run = _run_at(tmp_path, 400)
    resume_plan(run, TrainRequest(push_interval=(1.5, 3.0)))
    env_cfg, _ = train.load_config(run)
    assert env_cfg.randomization.push_interval_s == (1.5, 3.0)
    assert (env_cfg.randomization.push_velocity_min, env_cfg.randomization.push_velocity) == (0.15, 0.35)  # kept
    assert [(s["from_env_steps"], s["push_velocity"], s["push_interval_s"]) for s in train.training_stages(run)] == [
        (0, [0.15, 0.35], [2.0, 5.0]), (400, [0.15, 0.35], [1.5, 3.0])]


def test_a_resumed_run_goes_on_with_older_imu_readings_as_a_recorded_stage(tmp_path):
    from toddlerbot.rl import train
    from toddlerbot.rl.launch import TrainRequest, resume_plan

    run = _run_at(tmp_path, 400)
    resume_plan(run, TrainRequest(imu_age=(0.0, 0.02)))
    env_cfg, _ = train.load_config(run)
    assert env_cfg.randomization.imu_age_s == (0.0, 0.02)
    assert env_cfg.randomization.push_interval_s == (2.0, 5.0)  # kept
    assert [(s["from_env_steps"], s["imu_age_s"], s["push_interval_s"]) for s in train.training_stages(run)] == [
        (0, [0.0, 0.0], [2.0, 5.0]), (400, [0.0, 0.02], [2.0, 5.0])]


def test_stages_recorded_before_the_interval_could_change_read_as_the_configuration_s(tmp_path):
    import json

    from toddlerbot.rl import train

    run = _run_at(tmp_path, 400)
    raw = json.loads((run / "config.json").read_text())
    raw["stages"] = [{"from_env_steps": 0, "push_velocity": [0.15, 0.35], "num_timesteps": 1000}]  # an older run's
    (run / "config.json").write_text(json.dumps(raw))
    assert train.training_stages(run) == [{"from_env_steps": 0, "push_velocity": [0.15, 0.35],
                                           "push_interval_s": [2.0, 5.0], "imu_age_s": [0.0, 0.0],
                                           "terrain": "flat", "terrain_seed": 0, "terrain_start": 0.25,
                                           "desired_kl": 0.01, "num_timesteps": 1000}]  # fresh IMU, flat, its KL


def test_a_resumed_run_goes_on_on_other_ground_as_a_recorded_stage(tmp_path):
    """A terrain curriculum: `rl train --resume --terrain ... --terrain-seed ...` from the last checkpoint."""
    from toddlerbot.rl import train
    from toddlerbot.rl.launch import TrainRequest, resume_plan

    run = _run_at(tmp_path, 400)
    resume_plan(run, TrainRequest(terrain="rough:height=0.02", terrain_seed=5))
    env_cfg, _ = train.load_config(run)
    assert (env_cfg.terrain, env_cfg.terrain_seed) == ("rough:height=0.02,cell=0.1", 5)
    assert [(s["from_env_steps"], s["terrain"], s["terrain_seed"]) for s in train.training_stages(run)] == [
        (0, "flat", 0), (400, "rough:height=0.02,cell=0.1", 5)]
    with pytest.raises(ToddlerbotError, match=r"^--terrain 'rough:height=0\.5': .*height"):
        resume_plan(run, TrainRequest(terrain="rough:height=0.5"))


def test_a_resumed_run_goes_on_from_a_smaller_start_square_as_a_recorded_stage(tmp_path):
    """`rl train --resume --terrain-start 0.08`: the training ground's flat start square shrinks to the feet, so
    every episode walks onto the tiles at once (docs/rl.md "Walking on terrain")."""
    from toddlerbot.rl import train
    from toddlerbot.rl.launch import TrainRequest, resume_plan

    run = _run_at(tmp_path, 400)
    resume_plan(run, TrainRequest(terrain="rough:height=0.01", terrain_start=0.08))
    env_cfg, _ = train.load_config(run)
    assert env_cfg.terrain_start == 0.08
    assert [(s["from_env_steps"], s["terrain_start"]) for s in train.training_stages(run)] == [(0, 0.25), (400, 0.08)]


def test_a_new_run_takes_its_kl_target_from_the_option_and_refuses_a_bad_one(tmp_path):
    from toddlerbot.rl.launch import TrainRequest, new_run_plan

    assert new_run_plan(tmp_path / "run", TrainRequest(smoke=True), write=False).ppo.desired_kl == 0.01
    assert new_run_plan(tmp_path / "run", TrainRequest(smoke=True, desired_kl=0.03), write=False).ppo.desired_kl \
        == 0.03
    with pytest.raises(ToddlerbotError, match=r"^--desired-kl: desired KL 2\.0: expected 0 < KL <= 1$"):
        new_run_plan(tmp_path / "run", TrainRequest(smoke=True, desired_kl=2.0), write=False)


def test_a_resumed_run_goes_on_with_another_kl_target_as_a_recorded_stage(tmp_path):
    """A continued policy whose step size sat at its floor: `rl train --resume --desired-kl 0.03` loosens PPO's KL
    target from the last checkpoint on (docs/rl.md "Walking on terrain")."""
    from toddlerbot.rl import train
    from toddlerbot.rl.launch import TrainRequest, resume_plan

    run = _run_at(tmp_path, 400)
    resume_plan(run, TrainRequest(desired_kl=0.03))
    _, ppo_cfg = train.load_config(run)
    assert ppo_cfg.desired_kl == 0.03
    assert [(s["from_env_steps"], s["desired_kl"]) for s in train.training_stages(run)] == [(0, 0.01), (400, 0.03)]


@pytest.mark.parametrize(("request_fields", "message"), [
    ({"desired_kl": 0.0}, r"^--desired-kl: desired KL 0\.0: expected 0 < KL <= 1$"),
    ({"terrain_start": 0.05}, r"^--terrain-start: terrain start 0\.05 m: expected a half-width of 0\.08-0\.25 m$"),
    ({"push_velocity": (0.5, 0.3)}, r"--push-velocity: push velocities 0\.5\.\.0\.3: expected"),
    ({"timesteps": 400}, r"--timesteps 400: the run is already at 400 PPO env steps; expected more"),
    ({"hand_force": 1.0}, r"^--hand-force: a resumed run keeps the settings it started with"),
    ({"push_interval": (3.0, 1.0)}, r"^--push-interval: push interval 3\.0\.\.1\.0: expected 0 < shortest"),
    ({"reward_weights": ("path_xy=5",)}, r"^--reward-weight: a resumed run keeps the settings it started with"),
    ({"num_envs": 8, "environment": "walk2"}, r"^--num-envs/--env: a resumed run keeps the settings it started"),
    ({"imu_age": (0.02, 0.01)}, r"^--imu-age: IMU age 0\.02\.\.0\.01: expected 0 <= youngest <= oldest, s$"),
    ({"imu_age": (0.0, 0.03)}, r"^--imu-age: IMU age up to 0\.03 s: expected at most the control period 0\.02 s$"),
    ({"num_envs": 8}, r"a resumed run keeps the settings .*only --push-velocity, --push-interval, --imu-age, "
                      r"--terrain, --terrain-seed, --terrain-start, --desired-kl and --timesteps start a next stage"),
])
def test_a_resume_refuses_a_bad_stage_or_other_changes_and_leaves_the_run_as_it_was(tmp_path, request_fields,
                                                                                     message):
    from toddlerbot.rl.launch import TrainRequest, resume_plan

    run = _run_at(tmp_path, 400)
    before = (run / "config.json").read_text()
    with pytest.raises(ToddlerbotError, match=message):
        resume_plan(run, TrainRequest(**request_fields))
    assert (run / "config.json").read_text() == before


def test_the_shipped_push_policy_is_the_cpu_recipe_with_the_band_and_survives_0p2_mps_kicks():
    """`walk_rl_push.npz` (docs/rl.md "Pushes near the largest", "Mirror symmetry"): in the benchmark 0 falls in
    30 trials of 0.2 m/s kicks run symmetric as walk-rl does (2 alone; the default policy 4, alone 8). Six trials
    here, at most two falls: a rate with margin, not one trajectory."""
    from toddlerbot.policies.rl_inference import RLPolicyFile
    from toddlerbot.policies.walk_rl import resolve_weights
    from walk_support import kick_trials

    path = resolve_weights("walk_rl_push")
    meta = RLPolicyFile(path).meta
    assert meta["push_velocity"] == [0.15, 0.35] and meta["backend"] == "cpu"
    assert meta["device"].startswith("CPU") and meta["walltime_s"] <= 7200  # the CPU recipe within two hours
    trials = kick_trials(path, "kicks 0.2 m/s", slice(None, 3))
    assert sum(t.fell for t in trials) <= 2, [(t.command, t.seed, t.fall_time) for t in trials]


def test_the_shipped_kick_policy_trained_with_frequent_pushes_survives_0p3_mps_kicks():
    """`walk_rl_kicks.npz` (docs/rl.md "Pushes more often"): pushes of 0.15-0.35 m/s every 1.5-3 s and the mirror
    loss; in the benchmark 0 falls in 30 trials of 0.3 m/s kicks on seeds 0-2 and 1 in 30 on seeds 3-5 (the
    default policy 5 and 8). Six trials here, at most one fall: a rate with margin, not one trajectory."""
    from toddlerbot.policies.rl_inference import RLPolicyFile
    from toddlerbot.policies.walk_rl import resolve_weights
    from walk_support import kick_trials

    path = resolve_weights("walk_rl_kicks")
    meta = RLPolicyFile(path).meta
    assert meta["push_velocity"] == [0.15, 0.35] and meta["push_interval_s"] == [1.5, 3.0]
    assert meta["mirror_loss"] == 1.0 and meta["backend"] == "cpu"
    assert meta["device"].startswith("CPU") and meta["walltime_s"] <= 7200  # the CPU recipe within two hours
    trials = kick_trials(path, "kicks 0.3 m/s", slice(None, 3))
    assert sum(t.fell for t in trials) <= 1, [(t.command, t.seed, t.fall_time) for t in trials]
