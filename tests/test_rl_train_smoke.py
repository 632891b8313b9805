"""SMOKE TRAINING RUN (slow: a few minutes on a 2-core CPU, mostly XLA compilation).

`toddlerbot rl train --smoke` (on the CPU backend, this machine having no GPU) makes a tiny DAgger warm start,
runs one PPO epoch and stops, `--resume` continues from its checkpoint (optimiser state
included) for the second epoch, and the export of the result acts exactly like the JAX policy. Each CLI call is
its own process (the smoke run sets its XLA flags before JAX starts); a persistent compilation cache lets the
resumed run reuse the first run's compiled program. Both calls log to TensorBoard (the default) and to W&B
(``--wandb`` with the fake ``wandb`` module of ``tests/fake_wandb``, which writes its calls to a file): the
dashboards are checked on this run rather than on a second training.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("brax")
pytest.importorskip("mujoco.mjx")

from dashboard_support import FAKE_WANDB_DIR, expected_scalars, numbers, read_jsonl, read_scalars  # noqa: E402
from toddlerbot.policies.rl_inference import RLPolicyFile  # noqa: E402
from toddlerbot.rl import config, export, train  # noqa: E402

pytestmark = pytest.mark.slow
SRC = Path(__file__).resolve().parents[1] / "src"
WANDB_CALLS = "wandb_calls.jsonl"
"""The fake W&B module's record of its calls, beside the run directory."""


def _cli(*args, cache: Path) -> str:
    path = os.pathsep.join([str(FAKE_WANDB_DIR), str(SRC), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "PYTHONPATH": path, "FAKE_WANDB_LOG": str(cache.parent / WANDB_CALLS),
           "JAX_COMPILATION_CACHE_DIR": str(cache), "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0"}
    out = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", *args], env=env, capture_output=True,
                         text=True, timeout=900)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return out.stdout


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("rl")
    run = root / "run"
    _cli("rl", "train", "--smoke", "--out", str(run), "--epochs", "1", "--wandb", "--wandb-mode", "offline",
         cache=root / "xla")
    ckpt1 = train.checkpoint_paths(run)
    first, _ = export.restore_checkpoint(ckpt1[-1], train.load_config(run)[1])
    # --timesteps: the same budget, so the same compiled program; it records the resume as the run's next stage
    _cli("rl", "train", "--resume", str(run), "--wandb", "--timesteps", str(config.SMOKE.num_timesteps),
         cache=root / "xla")
    final, history = export.restore_checkpoint(train.checkpoint_paths(run)[-1], train.load_config(run)[1])
    return run, first, ckpt1, final, history


def test_smoke_run_starts_from_the_dagger_warm_start(smoke_run):
    run = smoke_run[0]
    records = [json.loads(line) for line in (run / "imitation.jsonl").read_text().splitlines()]
    assert len(records) == config.SMOKE_IMITATION.iterations and records[0]["teacher_drives"]
    assert records[0]["samples"] == config.SMOKE_IMITATION.num_envs * config.SMOKE_IMITATION.steps
    assert np.isfinite(records[0]["bc_loss"])
    assert (run / train.WARM_START).stat().st_size > 1000
    assert json.loads((run / "config.json").read_text())["env"]["backend"] == "cpu"  # no GPU: the CPU backend


def test_smoke_run_trains_two_epochs_with_sane_metrics(smoke_run):
    run, _first, _, final, history = smoke_run
    steps = config.SMOKE.env_steps_per_update
    assert [h["env_steps"] for h in history] == [steps, 2 * steps]
    assert int(final.env_steps) == 2 * steps
    for h in history:
        assert np.isfinite(h["step_reward"]) and h["sps"] > 0
        assert 0 <= h["kl_mean"] < 1.0 and h["policy_dist_min_std"] > 0.3  # one small update from std 0.5
        assert config.SMOKE.lr_bounds[0] <= h["learning_rate"] <= config.SMOKE.lr_bounds[1]
        assert 0.0 <= h["fall_rate"] <= 1.0
    assert len((run / "metrics.jsonl").read_text().splitlines()) == 2
    assert (run / "training_curve.png").stat().st_size > 10_000
    assert json.loads((run / "config.json").read_text())["env"]["obs"]["gait_period"] > 0


def test_resume_restores_optimizer_state_and_continues(smoke_run):
    run, first, ckpt1, final, _ = smoke_run
    assert len(ckpt1) == 1 and len(train.checkpoint_paths(run)) == 2
    restored, _, hist = train.load_checkpoint(ckpt1[0], final)
    adam = lambda s: train.adam_moments(s.optimizer_state)  # noqa: E731
    # the first checkpoint holds Adam's moments and step count, not just the parameters
    assert int(adam(restored).count) == config.SMOKE.num_minibatches * config.SMOKE.num_updates_per_batch
    mu = jax.tree.leaves(adam(restored).mu)
    assert any(float(np.abs(m).max()) > 0 for m in mu)
    for a, b in zip(jax.tree.leaves(restored), jax.tree.leaves(first), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # training moved the parameters on from the first checkpoint
    moved = [not np.array_equal(a, b) for a, b in zip(jax.tree.leaves(final.params), jax.tree.leaves(first.params),
                                                       strict=True)]
    assert any(moved)
    # the resumed epoch continued from it: Adam's step count kept counting
    assert int(adam(final).count) == 2 * int(adam(restored).count)
    assert len(hist) == 1


def test_export_of_the_smoke_run_matches_jax_policy(smoke_run, tmp_path):
    from brax.training.agents.ppo import networks as ppo_networks

    run, _, _, final, _ = smoke_run
    path = export.export_run(run, tmp_path / "walk.npz")
    policy = RLPolicyFile(path)
    env_cfg, ppo_cfg = train.load_config(run)
    n_obs = policy.obs_mean.shape[0]
    critic = int(final.normalizer_params.mean["privileged_state"].shape[0])
    networks = train.make_networks({"state": (n_obs,), "privileged_state": (critic,)}, 12, ppo_cfg)
    act = ppo_networks.make_inference_fn(networks)(
        (final.normalizer_params, final.params.policy, final.params.value), deterministic=True)
    obs = np.random.default_rng(0).normal(size=(8, n_obs)).astype(np.float32)
    expected, _ = act({"state": obs, "privileged_state": np.zeros((8, critic), np.float32)}, jax.random.PRNGKey(0))
    np.testing.assert_allclose(np.stack([policy.action(o) for o in obs]), np.clip(np.asarray(expected), -1, 1),
                               atol=1e-5)
    warm = config.SMOKE_IMITATION.num_envs * config.SMOKE_IMITATION.steps
    assert policy.meta["env_steps"] == int(final.env_steps) + warm and policy.meta["imitation_env_steps"] == warm
    assert policy.meta["device"].startswith("CPU") and policy.meta["walltime_s"] > 0
    assert policy.obs_config == env_cfg.obs
    assert policy.reference is not None and policy.gain_scales is not None  # residual, walk-zmp's gains
    band = [env_cfg.randomization.push_velocity_min, env_cfg.randomization.push_velocity]
    half = config.SMOKE.env_steps_per_update
    assert policy.meta["push_velocity"] == band and policy.meta["push_stages"] == [[0, *band], [half, *band]]
    assert policy.meta["mirror_loss"] == ppo_cfg.mirror_loss == 0.0  # the smoke run trains without it
    assert policy.meta["seed"] == ppo_cfg.seed  # the training seed: a recipe's spread is over seeds
    assert policy.meta["push_interval_s"] == list(env_cfg.randomization.push_interval_s) == [2.0, 5.0]
    assert policy.meta["reward_weights"] == env_cfg.reward.weights and policy.meta["reward_weights"]["path_xy"] == 0
    first = RLPolicyFile(export.export_run(run, tmp_path / "first.npz", checkpoint=f"step_{half:012d}.msgpack"))
    assert first.meta["push_stages"] == [[0, *band]]  # the second stage began after this checkpoint
    assert policy.meta["push_interval_stages"] == [[0, 2.0, 5.0], [half, 2.0, 5.0]]


def test_smoke_run_dashboards_hold_the_json_lines_records(smoke_run):
    """TensorBoard (read with its own reader) and W&B hold every number of ``imitation.jsonl`` and
    ``metrics.jsonl``, at the run's environment steps (the warm start's included), over both training calls."""
    run = smoke_run[0]
    warm, epochs = read_jsonl(run / "imitation.jsonl"), read_jsonl(run / "metrics.jsonl")
    offset = warm[-1]["env_steps"]
    warm_steps, ppo_steps = [w["env_steps"] for w in warm], [offset + e["env_steps"] for e in epochs]
    scalars = read_scalars(run / "tensorboard")
    assert scalars == {**expected_scalars("dagger", warm, warm_steps), **expected_scalars("ppo", epochs, ppo_steps)}
    for key in ("policy_loss", "v_loss", "entropy_loss", "total_loss", "episode_reward", "episode_length", "kl_mean",
                "kl_max", "learning_rate", "sps", "walltime", "lin_vel_error", "ang_vel_error", "fall_rate"):
        assert [step for step, _ in scalars[f"ppo/{key}"]] == ppo_steps, key  # one point per epoch
    for key in ("bc_loss", "value_loss", "fall_rate", "step_reward"):
        assert len(scalars[f"dagger/{key}"]) == config.SMOKE_IMITATION.iterations, key
    assert len(list((run / "tensorboard").iterdir())) == 2  # one event file per training call

    calls = read_jsonl(run.parent / WANDB_CALLS)
    inits = [c for c in calls if c["call"] == "init"]
    assert len(inits) == 2 and inits[0]["id"] == inits[1]["id"] and inits[0]["mode"] == "offline"
    assert inits[1]["mode"] is None and inits[0]["config"]["ppo"]["num_envs"] == config.SMOKE.num_envs
    assert [c["exit_code"] for c in calls if c["call"] == "finish"] == [0, 0]
    logs = [c["data"] for c in calls if c["call"] == "log"]
    assert [{k[7:]: v for k, v in d.items()} for d in logs if "dagger/step" in d] == \
        [{**numbers(w), "step": step} for w, step in zip(warm, warm_steps)]
    assert [{k[4:]: v for k, v in d.items()} for d in logs if "ppo/step" in d] == \
        [{**numbers(e), "step": step} for e, step in zip(epochs, ppo_steps)]


def test_a_run_starts_from_another_runs_warm_start_without_dagger(smoke_run, tmp_path):
    """`--warm-start RUN` (the GPU run of docs/rl.md): the warm start is adopted as is, DAgger does not run again,
    the environment and networks are the source's, and PPO trains from it."""
    run = smoke_run[0]
    second = tmp_path / "from_warm"
    _cli("rl", "train", "--smoke", "--warm-start", str(run), "--out", str(second), "--epochs", "1", "--no-tensorboard",
         cache=run.parent / "xla")  # the source's shapes: the compilation cache serves this run
    assert (second / train.WARM_START).read_bytes() == (run / train.WARM_START).read_bytes()
    assert (second / "imitation.jsonl").read_text() == (run / "imitation.jsonl").read_text()  # no new DAgger
    mine, source = (json.loads((r / "config.json").read_text()) for r in (second, run))
    assert mine["env"] == source["env"] and mine["imitation"] == source["imitation"]
    assert mine["ppo"]["policy_hidden"] == source["ppo"]["policy_hidden"]
    records = read_jsonl(second / "metrics.jsonl")
    assert len(records) == 1 and records[0]["env_steps"] == config.SMOKE.num_timesteps // config.SMOKE.num_evals
    assert np.isfinite(records[0]["policy_loss"])


def test_a_run_continues_an_exported_policy_on_a_terrain(smoke_run, tmp_path):
    """`--init-policy FILE --terrain ...`: the new run takes the export's settings, starts from its actor and
    normaliser exactly (a critic fitted to the actor's returns beside them), trains on the terrain, and its export
    records the ground and the policy it continued."""
    run = smoke_run[0]
    exported = RLPolicyFile(export.export_run(run, tmp_path / "walk.npz"))
    second = tmp_path / "on_terrain"
    _cli("rl", "train", "--smoke", "--init-policy", str(exported.path), "--terrain", "rough:height=0.01",
         "--terrain-seed", "3", "--out", str(second), "--epochs", "1", "--no-tensorboard", cache=run.parent / "xla")
    env_cfg, ppo_cfg = train.load_config(second)
    assert (env_cfg.terrain, env_cfg.terrain_seed) == ("rough:height=0.01,cell=0.1", 3)
    assert env_cfg.reward.weights == exported.meta["reward_weights"]
    assert [env_cfg.randomization.push_velocity_min, env_cfg.randomization.push_velocity] == \
        exported.meta["push_velocity"]
    assert list(ppo_cfg.policy_hidden) == exported.meta["policy_hidden"]
    assert train.load_imitation_config(second).policy == str(exported.path.resolve())
    start = RLPolicyFile(export.export_run(second, tmp_path / "start.npz", checkpoint="warm_start"))
    for mine, theirs in zip(start.network.kernels + start.network.biases,
                            exported.network.kernels + exported.network.biases):
        np.testing.assert_array_equal(mine, theirs)
    np.testing.assert_allclose(start.network.obs_mean, exported.network.obs_mean, rtol=1e-6)
    np.testing.assert_allclose(start.network.obs_std, exported.network.obs_std, rtol=1e-6)
    np.testing.assert_allclose(start.action_std, exported.action_std, rtol=1e-6)
    critic = read_jsonl(second / "imitation.jsonl")
    assert len(critic) == config.SMOKE_IMITATION.iterations and np.isfinite(critic[-1]["value_loss"])
    trained = RLPolicyFile(export.export_run(second, tmp_path / "trained.npz"))
    assert trained.meta["terrain"] == "rough:height=0.01,cell=0.1"
    assert trained.meta["terrain_stages"] == [[0, "rough:height=0.01,cell=0.1", 3]]
    assert trained.meta["init_policy"] == str(exported.path.resolve())
    assert not np.array_equal(trained.network.kernels[-1], exported.network.kernels[-1])  # PPO moved it


def test_checkpoint_selection_walks_each_candidate_and_picks_the_fewest_falls(smoke_run, tmp_path):
    """`rl export --select K`: each of the last K checkpoints walks the same trials (the reach on a seed no
    benchmark uses); the one with the fewest falls, then the least stray, is selected and recorded in the export."""
    from toddlerbot.rl.selection import SELECTION_SEEDS, SelectionTrials, select_checkpoint

    run = smoke_run[0]
    trials = SelectionTrials(kick=0.0, seeds=(SELECTION_SEEDS[0],), seconds=1.0)
    best, rows = select_checkpoint(run, 2, trials)
    assert [r["checkpoint"] for r in rows] == [p.name for p in train.checkpoint_paths(run)[-2:]]
    assert all(r["trials"] == 10 and 0 <= r["falls"] <= 10 for r in rows)  # the ten commands of the reach
    ranked = sorted(rows, key=lambda r: (r["falls"], np.nan_to_num(r["stray_m"], nan=np.inf)))
    assert best == ranked[0]["checkpoint"]
    path = export.export_run(run, tmp_path / "selected.npz", checkpoint=best, extra_meta={"selection": rows})
    meta = RLPolicyFile(path).meta
    assert meta["checkpoint"] == best and meta["selection"] == rows
    assert not set(SELECTION_SEEDS) & set(range(6))  # disjoint from bench_walk_robustness's seeds 0-5
