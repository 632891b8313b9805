"""ONNX export of a walking policy: the graph maps the raw observation vector to the deterministic action exactly as
`RLPolicyFile.action` does (normalisation, swish MLP, ``tanh(mean)`` or ``clip(mean, -1, 1)``), and the policy's
metadata (motor names, home pose, leg indices, observation config, training metadata, gait reference and gain
schedule) travels in the model's ``metadata_props``, so the ``.onnx`` file alone runs ``walk-rl``.

The graph is written with the ``onnx`` package's helper API from the numpy arrays of an ``.npz`` export; a training
run is first exported to an ``.npz`` (`toddlerbot.rl.export.export_run`), so there is one path from a run to both
formats. Every export is checked against the numpy policy before it is kept (`verify_onnx`).
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_bytes
from toddlerbot.policies.rl_inference import ONNX_INPUT, ONNX_OUTPUT, NumpyNetwork, RLPolicyFile, _swish, onnx_metadata

OPSET = 17
"""ONNX operator set of the graph (Clip with tensor bounds, Slice with tensor arguments: opset >= 11)."""
IR_VERSION = 8
"""ONNX IR version written (opset 17's; read by every onnxruntime since 1.11)."""
ROUNDING_FACTOR = 4.0
"""The export check allows ONNX and numpy actions to differ by this many times the network's float32 rounding
error (`float32_rounding`): each of the two float32 evaluations carries such an error, in its own summation order;
their difference was measured at most 1.9 times it (docs/rl.md)."""
MIN_TOLERANCE = 1e-5
"""The check's smallest tolerance (2.5e-6 rad of motor target at action_scale 0.25): where the network's float32
rounding is ~0, onnxruntime's float32 tanh (up to 3.3e-7 from the exact one) still differs from numpy's."""
EXPORT_FORMATS = ("npz", "onnx")


def require_onnx():
    """The ``onnx`` package (in the ``[train]`` extra), or a one-line error."""
    try:
        import onnx
    except ImportError:
        raise ToddlerbotError("ONNX export needs the onnx package (pip install 'toddlerbot[train]')") from None
    return onnx


def policy_model(policy: RLPolicyFile):
    """The ``onnx.ModelProto`` of an ``.npz`` policy: input ``obs`` (batch, n_obs) float32, output ``action``
    (batch, n_actions) float32; hidden activation x * (0.5 + 0.5 tanh(x / 2)), written op for op as numpy does."""
    onnx = require_onnx()
    from onnx import TensorProto, helper, numpy_helper

    initializers = []

    def const(name: str, value) -> str:
        initializers.append(numpy_helper.from_array(np.asarray(value), name))
        return name

    nodes = []

    def op(kind: str, inputs: list[str], name: str, **attrs) -> str:
        nodes.append(helper.make_node(kind, inputs, [name], name=name, **attrs))
        return name

    half = const("half", np.float32(0.5))
    x = op("Sub", [ONNX_INPUT, const("obs_mean", policy.obs_mean)], "centred")
    x = op("Div", [x, const("obs_std", policy.obs_std)], "normalised")
    n_layers = len(policy.kernels)
    for i, (kernel, bias) in enumerate(zip(policy.kernels, policy.biases, strict=True)):
        x = op("MatMul", [x, const(f"layer{i}_kernel", kernel)], f"layer{i}_matmul")
        x = op("Add", [x, const(f"layer{i}_bias", bias)], f"layer{i}_linear")
        if i < n_layers - 1:  # swish through tanh, as `_swish`
            h = op("Mul", [x, half], f"layer{i}_half")
            h = op("Tanh", [h], f"layer{i}_tanh")
            h = op("Mul", [h, half], f"layer{i}_tanh_half")
            h = op("Add", [h, half], f"layer{i}_sigmoid")
            x = op("Mul", [x, h], f"layer{i}_swish")
    n_actions = policy.n_actions
    mean = op("Slice", [x, const("slice_start", np.array([0], np.int64)), const("slice_end", np.array([n_actions],
              np.int64)), const("slice_axis", np.array([1], np.int64))], "mean")
    if policy.distribution == "tanh_normal":
        nodes.append(helper.make_node("Tanh", [mean], [ONNX_OUTPUT], name="tanh_mean"))
    else:
        nodes.append(helper.make_node("Clip", [mean, const("low", np.float32(-1)), const("high", np.float32(1))],
                                      [ONNX_OUTPUT], name="clip_mean"))
    n_obs = policy.kernels[0].shape[0]
    graph = helper.make_graph(
        nodes, f"toddlerbot_{policy.environment}_policy",
        [helper.make_tensor_value_info(ONNX_INPUT, TensorProto.FLOAT, ["batch", n_obs])],
        [helper.make_tensor_value_info(ONNX_OUTPUT, TensorProto.FLOAT, ["batch", n_actions])],
        initializer=initializers)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="toddlerbot",
                              doc_string=f"{policy.environment} policy exported from {policy.path.name} "
                                         f"({policy.distribution})")
    model.ir_version = IR_VERSION
    helper.set_model_props(model, onnx_metadata(policy.metadata_arrays))
    onnx.checker.check_model(model)
    return model


def random_observations(policy: RLPolicyFile, n: int = 256, seed: int = 0) -> np.ndarray:
    """Observations drawn in the policy's normalised space: obs_mean + obs_std * z, half with z ~ N(0, 1), half
    with z uniform in [-3, 3]. (Raw standard-normal vectors lie up to hundreds of obs_std away from anything the
    robot observes, where float32 rounding alone moves the actions by ~1e-5, docs/rl.md.)"""
    rng = np.random.default_rng(seed)
    width = len(policy.obs_mean)
    z = np.concatenate([rng.normal(size=(n // 2, width)), rng.uniform(-3, 3, (n - n // 2, width))])
    return (policy.obs_mean + policy.obs_std * z).astype(np.float32)


def recorded_observations(npz_path: Path, steps: int = 50, command=(0.1, 0.0, 0.0)) -> np.ndarray:
    """The observation vectors the policy's runtime policy (`walk-rl`, `track`; numpy) gives its network driving the
    robot in the CPU simulator for ``steps`` control steps at ``command`` (m/s, m/s, rad/s) on the robot variant it
    was trained for (walk-rl: two per step, the history and its mirror image, the symmetric controller); fewer if it
    falls. Empty when its motors are not that packaged robot's."""
    from toddlerbot.policies import make_policy
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.robot.interface import CONTROL_DT
    from toddlerbot.runtime.runner import run_policy
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot, SimConfig

    policy_file = RLPolicyFile(npz_path)
    description = RobotDescription.load(variant=policy_file.meta.get("variant"))
    if tuple(policy_file.motor_names) != tuple(description.motor_names):
        return np.zeros((0, len(policy_file.obs_mean)), np.float32)
    robot = MuJoCoRobot(description, SimConfig(control_dt=policy_file.meta.get("ctrl_dt", CONTROL_DT)))
    player = make_policy(policy_file.meta.get("runtime_policy", "walk-rl"), robot, weights=npz_path)
    recording = _Recording(player.controller.policy)
    player.controller.policy = recording
    run_policy(robot, player, lambda _t: np.asarray(command, float), steps * robot.control_dt)
    return np.asarray(recording.observations, np.float32)


class _Recording:
    """An `RLPolicyFile` stand-in that keeps every observation it is asked to act on."""

    def __init__(self, policy: RLPolicyFile) -> None:
        self.policy, self.observations = policy, []

    def __getattr__(self, name: str):
        return getattr(self.policy, name)

    def action(self, obs: np.ndarray) -> np.ndarray:
        self.observations.append(np.array(obs, np.float32))
        return self.policy.action(obs)


def max_difference(onnx_policy: RLPolicyFile, numpy_policy: RLPolicyFile, observations: np.ndarray) -> float:
    """Largest absolute action difference between two loaded policies over ``observations`` (n, n_obs)."""
    if len(observations) == 0:
        return 0.0
    batch = onnx_policy.network.session.run(None, {ONNX_INPUT: np.asarray(observations, np.float32)})[0]
    single = np.stack([numpy_policy.action(o) for o in observations])
    return float(np.max(np.abs(batch - single)))


def network_means(network: NumpyNetwork, observations: np.ndarray, dtype: type) -> np.ndarray:
    """(n, n_legs) outputs of the network before ``tanh`` / ``clip`` for ``observations`` (n, n_obs), every
    operation in ``dtype`` on the export's float32 arrays."""
    x = (np.asarray(observations, np.float32).astype(dtype) - network.obs_mean.astype(dtype)) / \
        network.obs_std.astype(dtype)
    for i, (kernel, bias) in enumerate(zip(network.kernels, network.biases, strict=True)):
        x = x @ kernel.astype(dtype) + bias.astype(dtype)
        if i < len(network.kernels) - 1:
            x = _swish(x)
    return x[:, : network.n_actions]


def float32_rounding(network: NumpyNetwork, observations: np.ndarray) -> float:
    """The network's float32 rounding error on ``observations``: the largest difference between its outputs
    before tanh / clip evaluated in float32 and in float64. It grows with layer width and with weight and input
    magnitude (an input far outside its training spread: thousands of obs_std); tanh and clip only shrink it."""
    if len(observations) == 0:
        return 0.0
    exact = network_means(network, observations, np.float64)
    return float(np.max(np.abs(network_means(network, observations, np.float32) - exact)))


def verify_onnx(onnx_path: Path, npz_path: Path, record_steps: int = 50) -> dict[str, float | int]:
    """Compare an ONNX export with the numpy policy it came from on random and recorded observations: per set the
    largest action difference, the count and the tolerance (`ROUNDING_FACTOR` x `float32_rounding`, at least
    `MIN_TOLERANCE`); raises a one-line `ToddlerbotError` above a tolerance or if the metadata differs."""
    onnx_policy, numpy_policy = RLPolicyFile(onnx_path), RLPolicyFile(npz_path)
    for name, value in numpy_policy.metadata_arrays.items():
        other = onnx_policy.metadata_arrays.get(name)
        if other is None or other.dtype != value.dtype or other.shape != value.shape or \
                not np.array_equal(other, value):
            raise ToddlerbotError(f"{onnx_path}: metadata {name!r} differs from {npz_path} after the export")
    random_obs = random_observations(numpy_policy)
    recorded = recorded_observations(npz_path, record_steps) if record_steps else random_obs[:0]
    report: dict[str, float | int] = {}
    for kind, observations in (("random", random_obs), ("recorded", recorded)):
        difference = max_difference(onnx_policy, numpy_policy, observations)
        rounding = float32_rounding(numpy_policy.network, observations)
        tolerance = max(MIN_TOLERANCE, ROUNDING_FACTOR * rounding)
        report |= {kind: difference, f"n_{kind}": len(observations), f"{kind}_tolerance": tolerance}
        if not difference <= tolerance:
            raise ToddlerbotError(
                f"{onnx_path}: ONNX actions differ from the numpy policy by {difference:.3g} on {len(observations)} "
                f"{kind} observations, more than float32 rounding explains (tolerance {tolerance:.3g}: "
                f"{ROUNDING_FACTOR:g} x the network's float32 error {rounding:.3g} there, at least {MIN_TOLERANCE:g})")
    return report


@contextmanager
def _naming(shown: dict[Path, Path]) -> Iterator[None]:
    """Re-raise a `ToddlerbotError` with each temporary path of ``shown`` replaced by the path the user gave."""
    try:
        yield
    except ToddlerbotError as exc:
        message = str(exc)
        for temporary, given in shown.items():
            message = message.replace(str(temporary), str(given))
        raise ToddlerbotError(message) from None


def export_onnx(source: Path, out: Path, checkpoint: str | None = None, record_steps: int = 50):
    """Write the ONNX export of ``source`` (a training run directory or an ``.npz`` export) to ``out`` after
    checking it (in a temporary folder) against the numpy policy (`verify_onnx`); returns (path, verification
    report). Nothing is written when the check fails; messages name ``source`` and ``out``, never a temporary
    file."""
    source, out = Path(source), Path(out)
    require_onnx()
    if not source.exists():
        raise ToddlerbotError(f"{source}: no training run directory or exported .npz there")
    with tempfile.TemporaryDirectory() as tmp:
        candidate, npz = Path(tmp) / "policy.onnx", Path(tmp) / "policy.npz"
        with _naming({candidate: out, npz: source}):
            if source.is_dir():
                from toddlerbot.rl.export import export_run

                export_run(source, npz, checkpoint=checkpoint)
            elif checkpoint is not None:
                raise ToddlerbotError(f"--checkpoint {checkpoint}: only for a training run directory, not the file "
                                      f"{source}")
            else:
                npz = source
            data = policy_model(RLPolicyFile(npz)).SerializeToString()
            candidate.write_bytes(data)
            report = verify_onnx(candidate, npz, record_steps)
    return atomic_write_bytes(out, data), report

