"""ONNX export of walking policies: the graph equals the numpy policy, the metadata travels in the model, and
walk-rl runs from the .onnx file alone with the same checks as from the .npz."""

import json
import sys

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")

from cli_support import run_main  # noqa: E402
from toddlerbot.errors import ToddlerbotError  # noqa: E402
from toddlerbot.policies.rl_inference import ONNX_INPUT, RLPolicyFile  # noqa: E402
from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS, WalkRLPolicy  # noqa: E402
from toddlerbot.rl import onnx_export  # noqa: E402
from toddlerbot.rl.onnx_export import export_onnx, random_observations, recorded_observations  # noqa: E402

TOL = 1e-5


def _max_diff(onnx_policy, numpy_policy, observations):
    batch = onnx_policy.network.session.run(None, {ONNX_INPUT: observations.astype(np.float32)})[0]
    single = np.stack([onnx_policy.action(o) for o in observations])  # the runtime's one-row path
    numpy_actions = np.stack([numpy_policy.action(o) for o in observations])
    np.testing.assert_array_equal(batch, single)
    return float(np.max(np.abs(batch - numpy_actions))), numpy_actions


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """The shipped walk_rl.npz exported to ONNX (with the exporter's own check) and both loaded."""
    out = tmp_path_factory.mktemp("onnx") / "walk_rl.onnx"
    path, report = export_onnx(DEFAULT_WEIGHTS, out, record_steps=40)
    return RLPolicyFile(path), RLPolicyFile(DEFAULT_WEIGHTS), report


def test_shipped_policy_onnx_equals_numpy_on_random_and_recorded_observations(shipped):
    onnx_policy, numpy_policy, report = shipped
    assert report["n_random"] == 256 and report["n_recorded"] == 2 * 40  # the history and its mirror per step
    assert report["random"] <= TOL and report["recorded"] <= TOL
    # its float32 rounding (~3e-7) is far below the smallest tolerance, which therefore applies
    assert report["random_tolerance"] == report["recorded_tolerance"] == onnx_export.MIN_TOLERANCE == TOL
    assert numpy_policy.distribution == "normal"  # the CPU recipe's file: the action is clip(mean, -1, 1)
    rng_obs = random_observations(numpy_policy, 64, seed=11)
    diff, actions = _max_diff(onnx_policy, numpy_policy, rng_obs)
    assert diff <= TOL
    assert np.abs(actions).max() > 0.1  # a network that does something
    recorded = recorded_observations(DEFAULT_WEIGHTS, steps=20)
    assert recorded.shape == (2 * 20, 1245)
    diff, _ = _max_diff(onnx_policy, numpy_policy, recorded)
    assert diff <= TOL
    graph_ops = [n.op_type for n in onnx.load(str(onnx_policy.path)).graph.node]
    assert graph_ops[-1] == "Clip" and graph_ops.count("MatMul") == 4


def test_a_file_without_a_distribution_acts_with_tanh_of_the_mean_in_numpy_and_onnx(tmp_path):
    """Round 1's files (tanh-Normal PPO) carry no `distribution` entry: their action is tanh(mean), not the clip."""
    data = {k: v for k, v in np.load(DEFAULT_WEIGHTS, allow_pickle=False).items() if k != "distribution"}
    np.savez(tmp_path / "round1.npz", **data)
    clipped, tanh_policy = RLPolicyFile(DEFAULT_WEIGHTS), RLPolicyFile(tmp_path / "round1.npz")
    assert tanh_policy.distribution == "tanh_normal"
    observations = random_observations(clipped, 32, seed=5)
    means = np.stack([clipped.action(o) for o in observations])
    inside = np.abs(means) < 1.0  # where the clip is the mean itself
    assert inside.mean() > 0.5
    actions = np.stack([tanh_policy.action(o) for o in observations])
    np.testing.assert_allclose(actions[inside], np.tanh(means[inside]), atol=1e-6)
    path, report = export_onnx(tmp_path / "round1.npz", tmp_path / "round1.onnx", record_steps=0)
    assert report["random"] <= TOL
    assert [n.op_type for n in onnx.load(str(path)).graph.node][-1] == "Tanh"


def test_metadata_round_trip_is_exact(shipped):
    onnx_policy, numpy_policy, _ = shipped
    assert onnx_policy.format == "onnx" and numpy_policy.format == "npz"
    assert set(onnx_policy.metadata_arrays) == set(numpy_policy.metadata_arrays) == {
        "home_motor_pos", "leg_motor_index", "leg_motors", "meta", "motor_names", "obs_config", "action_std",
        "distribution", "kp_stance_scale", "kp_swing_scale", "ref_contact", "ref_leg_motor_pos", "ref_period",
        "ref_vx", "ref_vy", "ref_yaw"}  # the residual policy carries its gait reference and gain schedule
    for name, value in numpy_policy.metadata_arrays.items():
        other = onnx_policy.metadata_arrays[name]
        assert other.dtype == value.dtype and other.shape == value.shape
        np.testing.assert_array_equal(other, value)
    assert onnx_policy.motor_names == numpy_policy.motor_names and len(onnx_policy.motor_names) == 30
    assert onnx_policy.meta == numpy_policy.meta and onnx_policy.meta["ctrl_dt"] == 0.02
    assert onnx_policy.obs_config == numpy_policy.obs_config and onnx_policy.obs_config.history == 15
    np.testing.assert_array_equal(onnx_policy.leg_motor_index, numpy_policy.leg_motor_index)
    props = {p.key: p.value for p in onnx.load(str(onnx_policy.path)).metadata_props}
    assert json.loads(props["toddlerbot.motor_names"])[0] == "neck_yaw_drive"
    assert json.loads(props["toddlerbot.meta"])["ctrl_dt"] == 0.02


def _residual_policy(tmp_path, motor_names=None, big_unit=0.0):
    """A small residual policy in the current format (Gaussian: clip(mean)) with a gait reference and gain schedule.
    ``big_unit``: the second hidden layer's first unit is this constant, which every output's bias cancels (means
    as small as without it, but summed in float32 next to a large number: their rounding error is ~ulp(big_unit))."""
    pytest.importorskip("jax")
    import itertools

    from toddlerbot.policies.rl_inference import GaitReference, ObsConfig
    from toddlerbot.rl.config import EnvConfig
    from toddlerbot.rl.export import write_policy
    from toddlerbot.robot.description import RobotDescription

    description = RobotDescription.load()
    obs = ObsConfig(history=3, gait_period=0.6)
    n_in = obs.history * obs.frame_size(30, 12)
    rng = np.random.default_rng(4)
    arrays = {}
    for i, (a, b) in enumerate(itertools.pairwise([n_in, 48, 32, 12])):
        gain = 4.0 if b == 12 else 1.0  # a trained-looking head: some means beyond +-1, so clipping is exercised
        arrays[f"layer{i}_kernel"] = (rng.normal(size=(a, b)) * gain / np.sqrt(a)).astype(np.float32)
        arrays[f"layer{i}_bias"] = rng.normal(size=b).astype(np.float32) * 0.1
    if big_unit:
        arrays["layer1_kernel"][:, 0], arrays["layer1_bias"][0] = 0.0, big_unit  # swish(big_unit) = big_unit
        arrays["layer2_kernel"][0, :] = 1.0
        arrays["layer2_bias"] -= big_unit
    arrays["obs_mean"] = rng.normal(size=n_in).astype(np.float32) * 0.1
    arrays["obs_std"] = rng.uniform(0.05, 1.0, n_in).astype(np.float32)
    arrays["distribution"], arrays["action_std"] = np.array("normal"), np.full(12, 0.4, np.float32)
    stance = (rng.uniform(size=(3, 3, 3, 10, 2)) > 0.5) * 1.0
    reference = GaitReference(np.linspace(-0.1, 0.15, 3), np.linspace(-0.08, 0.08, 3), np.linspace(-0.4, 0.4, 3), 0.6,
                              rng.normal(size=(3, 3, 3, 10, 12)) * 0.05, stance)
    swing = np.zeros((2, 30))
    swing[0, :6], swing[1, 6:12] = 0.7, 0.8
    space = {**reference.arrays(), "kp_stance_scale": np.full(30, 1.1), "kp_swing_scale": swing}
    path = write_policy(tmp_path / "residual.npz", arrays, EnvConfig(obs=obs), {"run": "test"}, description, space)
    if motor_names is not None:
        data = dict(np.load(path))
        data["motor_names"] = np.array(motor_names)
        np.savez(path, **data)
    return path


def test_residual_policy_with_reference_and_gains_round_trips(tmp_path):
    npz = _residual_policy(tmp_path)
    path, report = export_onnx(npz, tmp_path / "residual.onnx", record_steps=15)
    assert report["random"] <= TOL and report["recorded"] <= TOL and report["n_recorded"] == 2 * 15
    onnx_policy, numpy_policy = RLPolicyFile(path), RLPolicyFile(npz)
    assert numpy_policy.distribution == "normal"
    for name in ("ref_vx", "ref_leg_motor_pos", "ref_contact", "ref_period", "kp_stance_scale", "kp_swing_scale",
                 "action_std", "distribution"):
        np.testing.assert_array_equal(onnx_policy.metadata_arrays[name], numpy_policy.metadata_arrays[name])
        assert onnx_policy.metadata_arrays[name].dtype == numpy_policy.metadata_arrays[name].dtype
    np.testing.assert_array_equal(onnx_policy.reference.leg_motor_pos, numpy_policy.reference.leg_motor_pos)
    diff, actions = _max_diff(onnx_policy, numpy_policy, random_observations(numpy_policy, 128, seed=2))
    assert diff <= TOL
    assert 0 < np.mean(np.abs(actions) == 1.0) < 1  # clip(mean, -1, 1) exercised and not everywhere
    assert [n.op_type for n in onnx.load(str(path)).graph.node][-1] == "Clip"


def _drive_both(npz_path, onnx_path, steps, command):
    """Motor targets and gains of walk-rl from the .npz and from the .onnx, both fed the observations of one
    simulated robot (driven by the .npz policy)."""
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot

    robot = MuJoCoRobot()
    from_npz, from_onnx = WalkRLPolicy(robot, npz_path), WalkRLPolicy(robot, onnx_path)
    obs = robot.reset()
    from_npz.reset(obs)
    from_onnx.reset(obs)
    rows = []
    for _ in range(steps):
        a, b = from_npz.act(obs, command), from_onnx.act(obs, command)
        rows.append((a.motor_targets, b.motor_targets, a.kp, b.kp))
        obs = robot.step(a.motor_targets, a.kp, a.kd)
    return rows


def test_walk_rl_from_onnx_sends_the_npz_motor_targets(shipped, tmp_path):
    onnx_policy, _, _ = shipped
    rows = _drive_both(DEFAULT_WEIGHTS, onnx_policy.path, 25, np.array([0.1, 0.0, 0.0]))
    targets_npz = np.array([r[0] for r in rows])
    targets_onnx = np.array([r[1] for r in rows])
    assert np.max(np.abs(targets_npz - targets_onnx)) <= 0.25 * TOL  # action_scale x action tolerance
    assert np.ptp(targets_npz, axis=0).max() > 1e-3  # the targets move over the 25 steps
    # a residual policy with a gain schedule: same targets and the same P gains
    npz = _residual_policy(tmp_path)
    path, _ = export_onnx(npz, tmp_path / "residual.onnx", record_steps=0)
    rows = _drive_both(npz, path, 10, np.array([0.05, 0.0, 0.1]))
    assert max(np.max(np.abs(a - b)) for a, b, _, _ in rows) <= 0.25 * TOL
    assert all(np.array_equal(ka, kb) for _, _, ka, kb in rows) and rows[0][2] is not None


def test_wrong_motor_set_is_refused_in_one_line(tmp_path, monkeypatch, capsys):
    names = list(RLPolicyFile(DEFAULT_WEIGHTS).motor_names)
    names[0], names[1] = names[1], names[0]
    npz = _residual_policy(tmp_path, motor_names=names)
    path, report = export_onnx(npz, tmp_path / "swapped.onnx")
    assert report["n_recorded"] == 0  # not the default robot's motors: nothing to record, random check only
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot

    with pytest.raises(ToddlerbotError, match="trained for motors") as info:
        WalkRLPolicy(MuJoCoRobot(), path)
    assert "\n" not in str(info.value)
    code, _, err = run_main(monkeypatch, capsys, "sim", "run", "--policy", "walk-rl", "--weights", path, "--seconds",
                        "0.1")
    assert code == 2 and err.count("\n") == 1 and "trained for motors ('neck_pitch_drive'" in err


def test_cli_export_from_npz_and_bad_format(tmp_path, monkeypatch, capsys):
    out = tmp_path / "w.onnx"
    code, stdout, _ = run_main(monkeypatch, capsys, "rl", "export", _residual_policy(tmp_path), "--format", "onnx",
                           "--out", out)
    assert code == 0 and out.is_file() and "max abs action difference" in stdout
    figures = [float(x) for x in stdout.split("difference:")[1].replace(",", " ").split() if x[0].isdigit()]
    assert figures[0] <= TOL and figures[1] == 256  # difference on 256 random observations
    code, _, err = run_main(monkeypatch, capsys, "rl", "export", DEFAULT_WEIGHTS, "--format", "tflite", "--out",
                        tmp_path / "x.tflite")
    assert code == 2 and err.count("\n") == 1 and "'--format': Value error, 'tflite' is not one of 'npz', 'onnx'" in err
    assert not (tmp_path / "x.tflite").exists()


def test_float32_rounding_beyond_1e5_is_accepted_within_its_measured_bound(tmp_path):
    """What refused a smoke run (inputs 1e5 obs_std out: ONNX and numpy 1.3e-5 apart): large intermediate values,
    whose float32 rounding both evaluations carry. Here a hidden unit at 1000 (ulp 6.1e-5) cancelled in the output."""
    npz = _residual_policy(tmp_path, big_unit=1000.0)
    numpy_policy = RLPolicyFile(npz)
    observations = random_observations(numpy_policy)
    exact = onnx_export.network_means(numpy_policy.network, observations, np.float64)
    assert np.abs(exact).min() < 0.01 and 0.2 < np.mean(np.abs(exact) < 1) < 0.8  # small means, half unclipped
    rounding = onnx_export.float32_rounding(numpy_policy.network, observations)
    assert 3e-5 < rounding < 1e-3  # between half an ulp of 1000 and a few tens of them
    path, report = export_onnx(npz, tmp_path / "big_unit.onnx", record_steps=0)
    assert TOL < report["random"] <= report["random_tolerance"] == pytest.approx(4 * rounding)
    assert report["random"] < report["random_tolerance"] / 4  # measured: ONNX within 2 x ulp(1000) of numpy
    diff, _ = _max_diff(RLPolicyFile(path), numpy_policy, observations)
    assert diff == report["random"]


def _perturbed_graph(monkeypatch, delta):
    """Make the exporter write its graph with ``delta`` added to one head weight (hidden unit 5 -> action 3)."""
    from onnx import numpy_helper

    real = onnx_export.policy_model

    def perturbed(policy):
        model = real(policy)
        kernel = next(t for t in model.graph.initializer if t.name == "layer2_kernel")
        weights = numpy_helper.to_array(kernel).copy()
        weights[5, 3] += delta
        kernel.CopyFrom(numpy_helper.from_array(weights, kernel.name))
        return model

    monkeypatch.setattr(onnx_export, "policy_model", perturbed)


@pytest.mark.parametrize(("big_unit", "delta", "tolerance"), [(0.0, 1e-3, 1e-4), (1000.0, 1e-2, 3e-3)],
                         ids=["ordinary", "large_rounding"])
def test_a_perturbed_weight_is_refused_in_one_line_naming_the_output(tmp_path, monkeypatch, capsys, big_unit, delta,
                                                                     tolerance):
    npz = _residual_policy(tmp_path, big_unit=big_unit)
    _perturbed_graph(monkeypatch, delta)
    out = tmp_path / "perturbed.onnx"
    with pytest.raises(ToddlerbotError, match="ONNX actions differ from the numpy policy by") as info:
        export_onnx(npz, out, record_steps=0)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{out}: ") and "on 256 random observations" in message
    figures = message.split(" by ")[1].split()[0], message.split("(tolerance ")[1].split(":")[0]
    difference, allowed = map(float, figures)
    assert allowed <= tolerance and difference > 5 * allowed
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["residual.npz"]  # no temporary left
    code, _, err = run_main(monkeypatch, capsys, "rl", "export", npz, "--format", "onnx", "--out", out)
    assert code == 2 and err.count("\n") == 1 and f"{out}: ONNX actions differ" in err and not out.exists()


def test_changed_metadata_is_refused_naming_the_output_and_the_source(tmp_path, monkeypatch):
    from onnx import helper

    npz = _residual_policy(tmp_path)
    real = onnx_export.policy_model

    def relabelled(policy):
        model = real(policy)
        props = {p.key: p.value for p in model.metadata_props} | {"toddlerbot.ref_period": "0.7"}
        del model.metadata_props[:]
        helper.set_model_props(model, props)
        return model

    monkeypatch.setattr(onnx_export, "policy_model", relabelled)
    out = tmp_path / "relabelled.onnx"
    with pytest.raises(ToddlerbotError) as info:
        export_onnx(npz, out, record_steps=0)
    assert str(info.value) == f"{out}: metadata 'ref_period' differs from {npz} after the export"
    assert not out.exists()


def test_onnx_runtime_missing_or_foreign_models_are_one_line_errors(shipped, tmp_path, monkeypatch):
    onnx_policy = shipped[0]
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # import fails as if not installed
    with pytest.raises(ToddlerbotError, match=r"needs onnxruntime, which is not installed") as info:
        RLPolicyFile(onnx_policy.path)
    assert "\n" not in str(info.value)
    monkeypatch.undo()
    (tmp_path / "junk.onnx").write_bytes(b"not a protobuf at all")
    with pytest.raises(ToddlerbotError, match="not a readable ONNX model"):
        RLPolicyFile(tmp_path / "junk.onnx")
    model = onnx.load(str(onnx_policy.path))
    del model.metadata_props[:]
    onnx.save(model, str(tmp_path / "bare.onnx"))
    with pytest.raises(ToddlerbotError, match="without toddlerbot policy metadata"):
        RLPolicyFile(tmp_path / "bare.onnx")


def _small_run(tmp_path):
    """A training run directory (config + one checkpoint of a small network) as `rl train` leaves it."""
    pytest.importorskip("brax")
    from ppo_support import small_run

    return small_run(tmp_path)


def test_small_run_exports_to_onnx_equal_to_its_npz(tmp_path, monkeypatch, capsys):
    run = _small_run(tmp_path)
    code, _, err = run_main(monkeypatch, capsys, "rl", "export", run, "--out", tmp_path / "run.npz")
    assert code == 0, err
    code, stdout, err = run_main(monkeypatch, capsys, "rl", "export", run, "--format", "onnx", "--out",
                             tmp_path / "run.onnx")
    assert code == 0, err
    assert "on 256 random observations" in stdout and "on 100 recorded" in stdout  # 50 steps x 2
    onnx_policy, numpy_policy = RLPolicyFile(tmp_path / "run.onnx"), RLPolicyFile(tmp_path / "run.npz")
    assert onnx_policy.meta["checkpoint"] == numpy_policy.meta["checkpoint"] == "step_000000004096.msgpack"
    assert onnx_policy.network.n_inputs == numpy_policy.network.n_inputs == 2 * (2 + 3 + 60 + 12 + 6)
    for observations in (random_observations(numpy_policy, 128, seed=8),
                         recorded_observations(tmp_path / "run.npz", steps=20)):
        diff, actions = _max_diff(onnx_policy, numpy_policy, observations)
        assert diff <= TOL and len(actions) in (128, 2 * 20)
    assert 0 < np.mean(np.abs(actions) == 1.0) < 1 or np.abs(actions).max() > 0.05


# diffusion policy ----------------------------------------------------------------------------------------------
def _dp_checkpoint(tmp_path, **changes):
    pytest.importorskip("torch")
    from dataclasses import replace

    from toddlerbot.dp.checkpoint import new_training_state, save_checkpoint
    from toddlerbot.dp.config import TINY

    cfg = replace(TINY, **changes).with_dims(5, 4, tuple(f"j{i}" for i in range(5)), tuple(f"a{i}" for i in range(4)))
    ranges = {"observation.state": (-np.ones(5), np.linspace(0.5, 2, 5)), "action": (np.zeros(4), np.arange(1, 5.0))}
    return save_checkpoint(tmp_path / "dp.pt", new_training_state(cfg, ranges))


@pytest.mark.parametrize("changes", [{"crop_size": 88}, {"encoder": "none"}], ids=["small_cnn_crop", "state_only"])
def test_dp_networks_in_onnx_equal_torch_and_sample_the_same_chunk(tmp_path, changes):
    import torch

    from toddlerbot.dp.checkpoint import load_policy
    from toddlerbot.dp.onnx_export import ENCODER_FILE, UNET_FILE, example_inputs, export_onnx
    from toddlerbot.dp.policy import IMAGE, STATE, normal_noise

    checkpoint = _dp_checkpoint(tmp_path, **changes)
    paths, report = export_onnx(checkpoint, tmp_path / "onnx")
    assert report[ENCODER_FILE] <= TOL and report[UNET_FILE] <= TOL
    assert report[f"{UNET_FILE} scale"] > 0.1  # outputs of a size where 1e-5 means something
    policy = load_policy(checkpoint)
    sessions = {name: ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]) for name, path in
                paths.items()}
    props = {p.key: p.value for p in onnx.load(str(paths[UNET_FILE])).metadata_props}
    assert json.loads(props["toddlerbot.dp_config"]) == json.loads(policy.config.to_json())
    np.testing.assert_allclose(json.loads(props["toddlerbot.action_half_range"]), [0.5, 1.0, 1.5, 2.0])
    # a batch of 3 (the graphs were traced with 2): deterministic DDIM chunks from onnxruntime and from torch
    inputs = example_inputs(policy, batch=3, seed=5)[ENCODER_FILE]
    cond = sessions[ENCODER_FILE].run(None, {k: v.numpy() for k, v in inputs.items()})[0]
    batch = {STATE: inputs["state"], **({IMAGE: inputs["images"]} if "images" in inputs else {})}
    expected = policy.sample(batch, generator=torch.Generator().manual_seed(0), sampler="ddim").numpy()
    x = normal_noise((3, policy.config.horizon, 4), torch.Generator().manual_seed(0), torch.device("cpu"))
    steps = policy.schedule.inference_timesteps(policy.config.inference_steps)
    for k, t in enumerate(steps):
        out = sessions[UNET_FILE].run(None, {"sample": x.numpy(), "timestep": np.full(3, t, np.int64),
                                             "cond": cond})[0]
        x = policy.schedule.ddim_step(x, torch.from_numpy(out), t, steps[k + 1] if k + 1 < len(steps) else -1)
    chunk = policy.action_norm.unnormalize(x).numpy()
    assert chunk.shape == expected.shape == (3, policy.config.horizon, 4)
    assert np.max(np.abs(chunk - expected)) <= 1e-5 * 4  # action units: up to 2 x half range 2
    assert np.ptp(expected) > 0.1


def test_dp_export_cli_formats(tmp_path, monkeypatch, capsys):
    checkpoint = _dp_checkpoint(tmp_path)
    code, stdout, err = run_main(monkeypatch, capsys, "dp", "export", checkpoint, "--format", "onnx", "--out",
                             tmp_path / "onnx")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "onnx").iterdir()) == ["noise_unet.onnx", "observation_encoder.onnx"]
    differences = [float(line.split("max abs difference ")[1].split()[0]) for line in stdout.splitlines()]
    assert len(differences) == 2 and max(differences) <= TOL
    code, _, err = run_main(monkeypatch, capsys, "dp", "export", checkpoint, "--format", "tflite", "--out",
                        tmp_path / "x")
    assert code == 2 and err.count("\n") == 1 and "'--format': Value error, 'tflite' is not one of 'pt', 'onnx'" in err


def _with_dtype(index: str, name: str, dtype: str) -> str:
    raw = json.loads(index)
    raw["arrays"][name]["dtype"] = dtype
    return json.dumps(raw)


@pytest.mark.parametrize(("change", "expected"), [
    (lambda p: p.pop("toddlerbot.motor_names"), "metadata misses 'toddlerbot.motor_names'"),
    (lambda p: p.update({"toddlerbot.home_motor_pos": "[1, 2]"}), "malformed ONNX policy metadata"),
    (lambda p: p.update({"toddlerbot.policy": _with_dtype(p["toddlerbot.policy"], "obs_config", "|O")}),
     "dtype object"),
    (lambda p: p.update({"toddlerbot.motor_names": json.dumps(["a"] * 30)}), "trained for motors ('a', 'a', 'a')"),
], ids=["missing", "wrong_shape", "object_dtype", "other_motors"])
def test_tampered_onnx_metadata_is_a_one_line_error(shipped, tmp_path, change, expected):
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot

    model = onnx.load(str(shipped[0].path))
    props = {p.key: p.value for p in model.metadata_props}
    change(props)
    del model.metadata_props[:]
    onnx.helper.set_model_props(model, props)
    onnx.save(model, str(tmp_path / "tampered.onnx"))
    with pytest.raises(ToddlerbotError) as info:
        WalkRLPolicy(MuJoCoRobot(), tmp_path / "tampered.onnx")
    assert expected in str(info.value) and "\n" not in str(info.value)
