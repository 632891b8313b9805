"""Training checkpoints hold the whole state (optimiser included), restore exactly, and fail clearly."""

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("brax")
optax = pytest.importorskip("optax")

from typer.testing import CliRunner  # noqa: E402

from toddlerbot.cli.main import app  # noqa: E402
from toddlerbot.errors import ToddlerbotError  # noqa: E402
from toddlerbot.rl import train  # noqa: E402
from toddlerbot.rl.config import PPOConfig  # noqa: E402


def _state(hidden=(16, 8), seed=0):
    cfg = PPOConfig(num_envs=8, batch_size=8, policy_hidden=hidden, value_hidden=hidden)
    obs = {"state": (10,), "privileged_state": (14,)}
    networks = train.make_networks(obs, 12, cfg)
    optimizer = train.make_optimizer(cfg)
    state = train._initial_state(networks, optimizer, obs, jax.random.PRNGKey(seed))
    # one real Adam step so the moments are non-zero
    grads = jax.tree.map(lambda p: 0.1 * np.ones_like(p), state.params)
    updates, opt_state = optimizer.update(grads, state.optimizer_state, state.params)
    opt_state = train.with_learning_rate(opt_state, jax.numpy.asarray(2.5e-4))  # as the KL rule would
    return state.replace(params=optax.apply_updates(state.params, updates), optimizer_state=opt_state,
                         env_steps=jax.numpy.asarray(20480, jax.numpy.int32))


def test_checkpoint_round_trip_is_exact_including_adam_moments(tmp_path):
    state = _state()
    key = jax.random.PRNGKey(7)
    path = train.save_checkpoint(tmp_path, state, key, [{"env_steps": 20480, "step_reward": 0.1}])
    assert path.name == "step_000000020480.msgpack" and train.checkpoint_paths(tmp_path) == [path]
    template = _state(seed=1)  # same structure, different numbers
    restored, restored_key, history = train.load_checkpoint(path, template)
    for a, b in zip(jax.tree.leaves(restored), jax.tree.leaves(state), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    adam = train.adam_moments(restored.optimizer_state)
    assert float(train.learning_rate(restored.optimizer_state)) == pytest.approx(2.5e-4)
    assert int(adam.count) == 1 and float(np.abs(jax.tree.leaves(adam.mu)[0]).max()) > 0
    np.testing.assert_array_equal(np.asarray(restored_key), np.asarray(key))
    assert history == [{"env_steps": 20480, "step_reward": 0.1}]
    assert not list(tmp_path.glob("checkpoints/*.tmp"))  # written atomically


def test_checkpoint_of_another_network_is_a_clear_error(tmp_path):
    path = train.save_checkpoint(tmp_path, _state(hidden=(16, 8)), jax.random.PRNGKey(0), [])
    with pytest.raises(ToddlerbotError, match="not a checkpoint of this configuration"):
        train.load_checkpoint(path, _state(hidden=(32, 8)))


@pytest.mark.parametrize("content", [b"", b"\x00" * 7, b"not msgpack at all", b"\x81\xa5state\xc0"])
def test_empty_truncated_or_foreign_checkpoints_are_one_line_errors(tmp_path, content):
    good = train.save_checkpoint(tmp_path, _state(hidden=(16, 8)), jax.random.PRNGKey(0), [])
    bad = tmp_path / "bad.msgpack"
    bad.write_bytes(content or b"")
    with pytest.raises(ToddlerbotError, match=r"bad.msgpack: not a checkpoint") as info:
        train.load_checkpoint(bad, _state(hidden=(16, 8)))
    assert "\n" not in str(info.value)
    truncated = tmp_path / "truncated.msgpack"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(ToddlerbotError, match=r"truncated.msgpack: not a checkpoint"):
        train.load_checkpoint(truncated, _state(hidden=(16, 8)))


def test_checkpoint_with_non_finite_parameters_is_refused(tmp_path):
    state = _state(hidden=(16, 8))
    poisoned = jax.tree.map(lambda x: x * np.nan if np.issubdtype(np.asarray(x).dtype, np.floating) else x, state)
    path = train.save_checkpoint(tmp_path, poisoned, jax.random.PRNGKey(0), [])
    with pytest.raises(ToddlerbotError, match="non-finite parameters"):
        train.load_checkpoint(path, state)


@pytest.mark.parametrize("text", ["", "{", "[]", '{"env": {}, "ppo": {}}', '{"env": 1, "ppo": 2}'])
def test_malformed_run_config_is_a_one_line_error(tmp_path, text):
    (tmp_path / "config.json").write_text(text)
    with pytest.raises(ToddlerbotError, match=r"config.json: not a training configuration"):
        train.load_config(tmp_path)


def test_cli_resume_and_export_without_a_run_fail_with_one_line(tmp_path):
    runner = CliRunner()
    result = runner.invoke(app, ["rl", "train", "--resume", str(tmp_path)])
    assert result.exit_code != 0 and "config.json missing" in str(result.exception)
    result = runner.invoke(app, ["rl", "export", str(tmp_path)])
    assert result.exit_code != 0 and "config.json missing" in str(result.exception)
    result = runner.invoke(app, ["rl", "train", "--num-envs", "3", "--out", str(tmp_path / "x")])
    assert result.exit_code != 0 and "3 envs: expected a positive multiple of 4" in str(result.exception)
    result = runner.invoke(app, ["rl", "train", "--warm-start", str(tmp_path), "--out", str(tmp_path / "y")])
    assert result.exit_code != 0 and "no DAgger warm start there (warm_start.msgpack missing)" in str(result.exception)


def test_num_envs_scales_the_batch_and_keeps_rollouts_per_update():
    from toddlerbot.rl import config

    gpu = config.with_num_envs(config.FULL, 4096)  # the GPU run of docs/rl.md: 128 envs x 32 minibatches
    assert (gpu.num_envs, gpu.batch_size, gpu.num_minibatches) == (4096, 128, 32)
    assert gpu.env_steps_per_update == 4096 * gpu.unroll_length  # one rollout of every env per update
    cpu = config.with_num_envs(config.CPU, 64)
    assert (cpu.batch_size, cpu.env_steps_per_update) == (16, 64 * 20)
    smoke = config.with_num_envs(config.SMOKE, 3)  # 2 rollouts per env in 2 minibatches: any count
    assert (smoke.batch_size, smoke.env_steps_per_update) == (3, 2 * 3 * 5)
    with pytest.raises(ValueError, match="100 envs: expected a positive multiple of 32"):
        config.with_num_envs(config.FULL, 100)


def test_rl_export_writes_beside_the_run_and_never_into_the_package(tmp_path, monkeypatch, capsys):
    from cli_support import one_line_error, run_main
    from ppo_support import small_run
    from toddlerbot.policies.rl_inference import RLPolicyFile
    from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS

    run = small_run(tmp_path)
    shipped = DEFAULT_WEIGHTS.read_bytes()
    code, out, err = run_main(monkeypatch, capsys, "rl", "export", run)
    assert code == 0, err
    assert f"exported {run / 'policy.npz'}" in out and RLPolicyFile(run / "policy.npz").meta["ppo_env_steps"] == 4096
    assert DEFAULT_WEIGHTS.read_bytes() == shipped  # a user's experiment never replaces the default
    checkpoint = train.checkpoint_paths(run)[0]
    for target, why in ((checkpoint, "would overwrite this command's input"),
                        (run / "config.json", "would overwrite this command's input"),
                        (DEFAULT_WEIGHTS, "is inside the installed toddlerbot package")):
        before = target.read_bytes()
        code, _, err = run_main(monkeypatch, capsys, "rl", "export", run, "--out", target)
        assert why in one_line_error(code, err)
        assert target.read_bytes() == before
    code, _, err = run_main(monkeypatch, capsys, "rl", "export", run, "--ship", "--out", tmp_path / "x.npz")
    assert one_line_error(code, err) == "error: --ship writes the package's shipped policy; drop --out"


def test_rl_export_ship_writes_the_shipped_policy_only_from_a_source_checkout(tmp_path, monkeypatch, capsys):
    from cli_support import one_line_error, run_main
    from ppo_support import small_run
    from toddlerbot.cli import output_paths
    from toddlerbot.policies.rl_inference import RLPolicyFile
    from toddlerbot.rl import walk_env

    run = small_run(tmp_path)
    installed = tmp_path / "site-packages" / "toddlerbot"  # a wheel install: no checkout around it
    (installed / "policies" / "weights").mkdir(parents=True)
    monkeypatch.setattr(output_paths, "PACKAGE_DIR", installed)
    monkeypatch.setattr(walk_env, "default_weights", lambda variant: installed / "policies" / "weights" / "walk_rl.npz")
    code, _, err = run_main(monkeypatch, capsys, "rl", "export", run, "--ship")
    assert "--ship writes into the package at" in one_line_error(code, err) and "not in a source checkout" in err
    assert not (installed / "policies" / "weights" / "walk_rl.npz").exists()
    checkout = tmp_path / "clone"  # src layout, pyproject and .git: pip install -e of a git clone
    package = checkout / "src" / "toddlerbot"
    (package / "policies" / "weights").mkdir(parents=True)
    (checkout / ".git").mkdir()
    (checkout / "pyproject.toml").write_text("[project]\nname = 'toddlerbot'\n")
    monkeypatch.setattr(output_paths, "PACKAGE_DIR", package)
    monkeypatch.setattr(walk_env, "default_weights", lambda variant: package / "policies" / "weights" / "walk_rl.npz")
    code, _, err = run_main(monkeypatch, capsys, "rl", "export", run, "--ship")
    assert code == 0, err
    assert RLPolicyFile(package / "policies" / "weights" / "walk_rl.npz").meta["ppo_env_steps"] == 4096


@pytest.mark.parametrize("damage", ["truncated", "random"])
def test_rl_export_of_a_damaged_checkpoint_is_one_line_in_both_formats(tmp_path, monkeypatch, capsys, damage):
    from cli_support import one_line_error, run_main
    from ppo_support import small_run

    run = small_run(tmp_path)
    checkpoint = train.checkpoint_paths(run)[0]
    good = checkpoint.read_bytes()
    checkpoint.write_bytes(good[: len(good) // 3] if damage == "truncated" else np.random.default_rng(0).bytes(4096))
    for extra in ([], ["--format", "onnx"]):
        code, _, err = run_main(monkeypatch, capsys, "rl", "export", run, *extra)
        assert one_line_error(code, err).startswith(f"error: {checkpoint}: not a checkpoint")
    assert not (run / "policy.npz").exists() and not (run / "policy.onnx").exists()
