"""SMOKE TRAINING RUN (slow: compiles the whole PPO program, several minutes on a 2-core CPU).

The `--smoke` configuration trains for one epoch, stops, resumes from its checkpoint (optimiser state included)
for a second epoch, and exports a policy whose numpy actions equal the JAX policy's. A persistent compilation
cache in the test's temporary directory lets the resumed run reuse the first run's compiled program.
"""

import json

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("brax")
pytest.importorskip("mujoco.mjx")

from toddlerbot.policies.rl_inference import RLPolicyFile  # noqa: E402
from toddlerbot.rl import config, export, train  # noqa: E402

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("rl")
    jax.config.update("jax_compilation_cache_dir", str(root / "xla_cache"))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    run = root / "run"
    first, history1 = train.train(run, config.smoke_env_config(), config.SMOKE, max_epochs=1)
    ckpt1 = train.checkpoint_paths(run)
    final, history = train.train(run, resume=True)
    return run, first, history1, ckpt1, final, history


def test_smoke_run_trains_two_epochs_with_sane_metrics(smoke_run):
    run, first, history1, _, final, history = smoke_run
    steps = config.SMOKE.env_steps_per_update
    assert [h["env_steps"] for h in history] == [steps, 2 * steps]
    assert int(final.env_steps) == 2 * steps
    for h in history:
        assert np.isfinite(h["step_reward"]) and h["sps"] > 0
        assert 0.0 <= h["fall_rate"] <= 1.0
    assert len((run / "metrics.jsonl").read_text().splitlines()) == 2
    assert json.loads((run / "config.json").read_text())["env"]["obs"]["gait_period"] > 0


def test_resume_restores_optimizer_state_and_continues(smoke_run):
    run, first, _, ckpt1, final, _ = smoke_run
    assert len(ckpt1) == 1 and len(train.checkpoint_paths(run)) == 2
    restored, _, hist = train.load_checkpoint(ckpt1[0], first)
    adam = lambda s: s.optimizer_state[1][0]  # noqa: E731 - (clip, adam) chain -> adam's ScaleByAdamState
    # the first checkpoint holds Adam's moments and step count, not just the parameters
    assert int(adam(restored).count) == config.SMOKE.num_minibatches * config.SMOKE.num_updates_per_batch
    mu = jax.tree.leaves(adam(restored).mu)
    assert any(float(np.abs(m).max()) > 0 for m in mu)
    for a, b in zip(jax.tree.leaves(restored), jax.tree.leaves(first), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # the resumed epoch continued from it: Adam's step count kept counting
    assert int(adam(final).count) == 2 * int(adam(restored).count)
    assert len(hist) == 1


def test_export_of_the_smoke_run_matches_jax_policy(smoke_run, tmp_path):
    from brax.training.agents.ppo import networks as ppo_networks

    run, _, _, _, final, _ = smoke_run
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
    np.testing.assert_allclose(np.stack([policy.action(o) for o in obs]), np.asarray(expected), atol=1e-5)
    assert policy.meta["env_steps"] == int(final.env_steps)
    assert policy.obs_config == env_cfg.obs
