"""PPO with a mirror-symmetry loss (`rl train --mirror-loss W`): the loss adds W x the policy's asymmetry, the
walking environment mirrors its actor observations and leg actions, and training with the loss makes a policy
its own mirror image (here on the tiny target task of `test_rl_ppo`, whose mirror is a sign and a swap)."""

import functools

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("brax")
jnp = jax.numpy


from ppo_support import CFG, TargetEnv, unroll_batch  # noqa: E402
from toddlerbot.errors import ToddlerbotError  # noqa: E402
from toddlerbot.policies.rl_inference import mirror_frame, mirror_leg_action  # noqa: E402
from toddlerbot.rl import train  # noqa: E402
from toddlerbot.rl.config import PPOConfig, smoke_env_config  # noqa: E402
from toddlerbot.rl.launch import TrainRequest, new_run_plan  # noqa: E402
from toddlerbot.rl.reference import standing_table  # noqa: E402
from toddlerbot.rl.walk_env import WalkEnv  # noqa: E402

PARTNER, SIGN = np.array([1, 0, 2, 3]), np.array([1.0, 1.0, -1.0, 1.0])
"""The target task's mirror: targets 0 and 1 swap, target 2 changes sign (an involution)."""


class MirroredTargetEnv(TargetEnv):
    """The target task with a mirror: the best policy (action = target) is its own mirror image."""

    def mirror_actor_obs(self, state):
        return 3.0 + SIGN * (state[..., PARTNER] - 3.0)  # the observation is 3 + 5 x target

    def mirror_action(self, action):
        return SIGN * action[..., PARTNER]


def test_the_loss_adds_the_weighted_asymmetry_to_ppos():
    weight = 2.5
    plain, mirrored = (train.PPO(MirroredTargetEnv(), PPOConfig(**{**CFG.__dict__, "mirror_loss": w}))
                       for w in (0.0, weight))
    ts = plain.initial_state(jax.random.PRNGKey(0))
    data = unroll_batch(plain, ts)
    key = jax.random.PRNGKey(4)
    loss, metrics = plain.loss(ts.params, ts.normalizer_params, data, key)
    with_mirror, mirror_metrics = mirrored.loss(ts.params, ts.normalizer_params, data, key)
    asymmetry = float(mirror_metrics["mirror_loss"])
    assert "mirror_loss" not in metrics and asymmetry > 1e-3  # a random network is not symmetric
    assert float(with_mirror) == pytest.approx(float(loss) + weight * asymmetry, rel=1e-6)
    # by hand: the mean action against the mirror image of the action on the mirrored observation
    apply = functools.partial(plain.networks.policy_network.apply, ts.normalizer_params, ts.params.policy)
    obs = data.observation
    mean, _ = apply(obs)
    mean_mirrored, _ = apply({**obs, "state": MirroredTargetEnv().mirror_actor_obs(obs["state"])})
    by_hand = np.mean(np.sum((np.asarray(mean) - SIGN * np.asarray(mean_mirrored)[..., PARTNER]) ** 2, axis=-1))
    assert asymmetry == pytest.approx(by_hand, rel=1e-5)


@pytest.mark.slow
def test_training_with_the_mirror_loss_makes_the_policy_its_own_mirror_image():
    """Same seed, same 25 updates: the loss's weight 10 leaves the policy far more symmetric than PPO alone, and
    it still learns the task."""
    finals = {}
    for weight in (0.0, 10.0):
        ppo = train.PPO(MirroredTargetEnv(), PPOConfig(**{**CFG.__dict__, "mirror_loss": weight}))
        ts = ppo.initial_state(jax.random.PRNGKey(0))
        env_state = ppo.reset(jax.random.PRNGKey(1))
        for i in range(ppo.epochs):
            ts, env_state, metrics = ppo.epoch(ts, env_state, jax.random.PRNGKey(10 + i))
        data = unroll_batch(ppo, ts)
        finals[weight] = (float(ppo.asymmetry(ts.params.policy, ts.normalizer_params, data.observation)),
                          1 - metrics["step_reward"])
    (plain, plain_error), (mirrored, mirrored_error) = finals[0.0], finals[10.0]
    print(f"asymmetry after training: {plain:.4f} without the loss, {mirrored:.4f} with it (squared error "
          f"{plain_error:.3f} / {mirrored_error:.3f})")
    assert mirrored < 0.25 * plain
    assert mirrored_error < 1.5 * plain_error


def test_the_walk_env_mirrors_every_frame_of_its_history_and_leg_actions():
    cfg = smoke_env_config()
    from toddlerbot.robot.description import RobotDescription

    description = RobotDescription.load()
    env = WalkEnv(cfg, description, reference=standing_table(description, cfg.command, period=0.6),
                  gain_scales=(np.ones(30), np.zeros((2, 30))))
    history = np.random.default_rng(0).normal(size=(2, cfg.obs.history, env.frame_size)).astype(np.float32)
    state = jnp.asarray(history.reshape(2, -1))
    mirrored = np.asarray(env.mirror_actor_obs(state)).reshape(history.shape)
    np.testing.assert_allclose(mirrored, mirror_frame(history, env.mirror, env.leg_index), atol=1e-6)
    np.testing.assert_allclose(np.asarray(env.mirror_actor_obs(env.mirror_actor_obs(state))), state, atol=1e-6)
    action = history[:, 0, :env.action_size]
    np.testing.assert_allclose(np.asarray(env.mirror_action(jnp.asarray(action))),
                               mirror_leg_action(action, env.mirror, env.leg_index), atol=1e-7)


def test_a_mirror_loss_needs_an_env_with_a_mirror_and_a_weight_of_at_least_zero(tmp_path):
    with pytest.raises(ToddlerbotError, match=r"mirror_loss 1\.0: the environment TargetEnv has no mirror"):
        train.PPO(TargetEnv(), PPOConfig(**{**CFG.__dict__, "mirror_loss": 1.0}))
    with pytest.raises(ToddlerbotError, match=r"--mirror-loss: mirror_loss -1\.0: expected a weight in \[0, 10000\]"):
        new_run_plan(tmp_path / "bad", TrainRequest(smoke=True, mirror_loss=-1.0))
    assert new_run_plan(tmp_path / "run", TrainRequest(smoke=True, mirror_loss=0.5)).ppo.mirror_loss == 0.5


def test_the_shipped_default_is_the_cpu_recipe_with_the_path_term_and_survives_0p3_mps_kicks():
    """`walk_rl.npz` (docs/rl.md "Pushes every 1-2 s"): trained on the CPU within two hours with the mirror loss,
    pushes of 0.15-0.35 m/s every 1.5-3 s and the path term, then a stage with pushes every 1-2 s; in the benchmark
    1 fall in 120 trials of 0.3 m/s kicks (seeds 0-11; the default before it 6). Six trials here, at most one fall:
    a rate with margin, not one trajectory."""
    from toddlerbot.policies.rl_inference import RLPolicyFile
    from toddlerbot.policies.walk_rl import resolve_weights
    from walk_support import kick_trials

    path = resolve_weights("walk_rl")
    meta = RLPolicyFile(path).meta
    assert meta["mirror_loss"] == 1.0 and meta["push_velocity"] == [0.15, 0.35] and meta["backend"] == "cpu"
    assert meta["device"].startswith("CPU") and meta["walltime_s"] <= 7200  # the CPU recipe within two hours
    assert meta["push_interval_s"] == [1.0, 2.0] and meta["reward_weights"]["path_xy"] == 5.0
    assert meta["push_interval_stages"] == [[0, 1.5, 3.0], [meta["push_stages"][1][0], 1.0, 2.0]]
    trials = kick_trials(path, "kicks 0.3 m/s", slice(3, 6))
    assert sum(t.fell for t in trials) <= 1, [(t.command, t.seed, t.fall_time) for t in trials]
