"""Inference of an exported RL walking policy without JAX (this runs on the robot's CPU at 50 Hz): numpy, or
onnxruntime for an ONNX export.

An exported policy is one ``.npz`` file holding

* ``layer{i}_kernel`` / ``layer{i}_bias``: the actor MLP (swish hidden activations, linear output),
* ``distribution``: ``normal`` (the output is the mean of a Gaussian whose samples the environment clips to
  [-1, 1], so the deterministic action is ``clip(mean, -1, 1)``; ``action_std`` holds its standard deviation)
  or, in files without this entry, ``tanh_normal`` (the output's first half is the pre-tanh mean; the
  deterministic action is ``tanh(mean)``),
* ``obs_mean`` / ``obs_std``: the observation normalisation learned during training,
* ``home_motor_pos``: motor angles of the home pose (rad, motor-id order), ``leg_motor_index``: the 12 leg
  motors, ``motor_names``; ``action_motor_index``: the motors the actions command, when not the legs (a tracking
  policy commands all 30),
* ``obs_config``: the `ObsConfig` as JSON, ``meta``: training metadata as JSON (``environment``: the registered
  training environment, ``walk`` when absent; ``runtime_policy``: the registered policy that plays it),
* for a residual policy (leg targets = gait reference + ``action_scale`` x action), the `GaitReference` arrays
  (``ref_vx``, ``ref_vy``, ``ref_yaw``, ``ref_period``, ``ref_leg_motor_pos``, ``ref_contact``), and for a policy
  trained with walk-zmp's leg gain schedule, ``kp_stance_scale`` / ``kp_swing_scale`` (`leg_gain_scale`),
* for a motion-tracking policy, the motion's tables (`toddlerbot.policies.track_observation.MotionTargets`).

or one ``.onnx`` file (`toddlerbot rl export --format onnx`): the graph maps the raw observation to the
deterministic action (normalisation, MLP, ``tanh`` or ``clip`` included) and every other array above travels in
the model's ``metadata_props`` (`onnx_metadata`), so `RLPolicyFile` reads and checks both the same way.

`obs_frame` is the single definition of one observation frame; the MJX environment builds its frames with the
same function (``xp=jax.numpy``), which is what makes training and deployment agree.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies.track_observation import MotionTargets

if TYPE_CHECKING:
    from toddlerbot.robot.mirror import Mirror

ACTION_DISTRIBUTION = "normal"
"""The action distribution `toddlerbot.rl` trains; exports before it record none and are ``tanh_normal``."""
LEG_GROUP = "leg"
"""The spec's motor group an RL walking policy commands (its actions, in motor-id order)."""


@dataclass(frozen=True)
class ObsConfig:
    """What the actor observes; stored in the exported file so inference builds the trained observation."""

    history: int = 15
    """Frames stacked in the actor observation (newest first)."""
    action_scale: float = 0.25
    """Leg motor target = home + action_scale * action, rad per unit action."""
    motor_vel_scale: float = 0.05
    """Motor speeds (rad/s) are multiplied by this."""
    gyro_scale: float = 0.25
    """IMU angular velocity (rad/s) is multiplied by this."""
    gait_period: float | None = None
    """s per gait cycle; the phase features are sin and cos of 2*pi*t/period. None (in a training config) means
    the walking reference's period; exported files always hold the number."""
    noise_motor_pos: float = 0.02
    """Training noise half-widths at noise level 1: motor angle rad, motor speed rad/s, gyro rad/s, gravity
    (unit vector). Not used at inference."""
    noise_motor_vel: float = 1.0
    noise_gyro: float = 0.1
    noise_gravity: float = 0.05

    def frame_size(self, n_motors: int, n_actions: int) -> int:
        """Features per frame (`frame_widths`)."""
        return sum(frame_widths(n_motors, n_actions))

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> ObsConfig:
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in json.loads(text).items() if k in names})


def frame_widths(n_motors: int, n_actions: int) -> tuple[int, ...]:
    """The parts of an `obs_frame`, in order: phase 2, command 3, motor angles relative to home and motor speeds
    (n_motors each), last action (n_actions, one per leg motor), gyro 3, gravity direction in the IMU frame 3."""
    return 2, 3, n_motors, n_motors, n_actions, 3, 3


def gravity_in_frame(quat, xp: ModuleType = np):
    """Unit gravity direction expressed in the frame with orientation quat (w, x, y, z, frame -> world)."""
    w, x, y, z = quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3]
    # third row of the rotation matrix, negated: R^T @ (0, 0, -1)
    return -xp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def obs_frame(t, command, motor_pos, home_motor_pos, motor_vel, last_action, gyro, gravity, cfg: ObsConfig,
              xp: ModuleType = np):
    """One actor observation frame (see `ObsConfig.frame_size`); t in s, command (vx, vy, yaw rate)."""
    angle = 2 * np.pi * t / cfg.gait_period
    phase = xp.stack([xp.sin(angle), xp.cos(angle)])
    return xp.concatenate([
        phase, command, motor_pos - home_motor_pos, motor_vel * cfg.motor_vel_scale, last_action,
        gyro * cfg.gyro_scale, gravity,
    ])


def mirror_frame(frame, mirror: Mirror, leg_motor_index, xp: ModuleType = np):
    """`obs_frame` of the robot's mirror image (frames on the last axis): half a gait cycle on (the other foot
    leads), sideways and turning commands negated, motors swapped with their partners (`Mirror`), the IMU's
    vectors reflected."""
    split = np.cumsum(frame_widths(len(mirror.partner), len(leg_motor_index))[:-1])
    phase, command, motor_pos, motor_vel, last_action, gyro, gravity = xp.split(frame, split, axis=-1)
    return xp.concatenate([
        -phase, command * xp.asarray([1.0, -1.0, -1.0]), mirror.motors(motor_pos, xp), mirror.motors(motor_vel, xp),
        mirror_leg_action(last_action, mirror, leg_motor_index, xp), mirror.gyro(gyro, xp),
        mirror.gravity(gravity, xp),
    ], axis=-1)


def mirror_leg_action(action, mirror: Mirror, leg_motor_index, xp: ModuleType = np):
    """A leg action (one number per leg motor, in ``leg_motor_index`` order) of the mirror image."""
    slot = np.full(len(mirror.partner), -1)
    slot[np.asarray(leg_motor_index)] = np.arange(len(leg_motor_index))
    partner_slot = slot[mirror.partner[np.asarray(leg_motor_index)]]
    return xp.asarray(mirror.sign[np.asarray(leg_motor_index)]) * action[..., partner_slot]


@dataclass(frozen=True)
class GaitReference:
    """The walking reference of a residual policy: leg motor angles and stance flags of the ZMP gait, tabulated on
    a grid of commands (``vx`` x ``vy`` x ``yaw`` axes, m/s and rad/s) x one gait cycle of ``period`` s in
    ``n_phase`` equal bins, and interpolated in between: multilinearly over the command (clamped to the grid) and
    linearly over the phase (periodic). `at` is the one definition for the environment (``xp=jax.numpy``) and
    the robot (numpy)."""

    vx: np.ndarray
    vy: np.ndarray
    yaw: np.ndarray
    period: float
    """s per gait cycle; phase bin p holds the gait at t = p * period / n_phase (mod period) of a walk started at
    t = 0."""
    leg_motor_pos: np.ndarray
    """(n_vx, n_vy, n_yaw, n_phase, n_legs) leg motor angles, rad (the ``leg`` group, motor-id order)."""
    contact: np.ndarray
    """(n_vx, n_vy, n_yaw, n_phase, 2) reference stance of the (left, right) foot, 1 = on the floor."""

    @property
    def n_phase(self) -> int:
        return self.leg_motor_pos.shape[3]

    def at(self, command, t, xp: ModuleType = np):
        """(leg motor angles (n_legs,) rad, stance flags (2,) in [0, 1]) at command (vx, vy, yaw rate) and time t
        (s since the gait started)."""
        index, weight = [], []
        for axis, x in zip((self.vx, self.vy, self.yaw), (command[0], command[1], command[2]), strict=True):
            axis = xp.asarray(axis)
            i = xp.clip(xp.searchsorted(axis, x, side="right") - 1, 0, axis.shape[0] - 2)
            w = xp.clip((x - axis[i]) / (axis[i + 1] - axis[i]), 0.0, 1.0)
            index.append(xp.stack([i, i + 1]))
            weight.append(xp.stack([1.0 - w, w]))
        s = xp.mod(t, self.period) / self.period * self.n_phase
        p = xp.floor(s)
        w = s - p
        p = p.astype(int) % self.n_phase
        index.append(xp.stack([p, (p + 1) % self.n_phase]))
        weight.append(xp.stack([1.0 - w, w]))
        i, j, k, q = (xp.reshape(ix, shape) for ix, shape in zip(index, _CORNERS, strict=True))
        w = (xp.reshape(weight[0], _CORNERS[0]) * xp.reshape(weight[1], _CORNERS[1])
             * xp.reshape(weight[2], _CORNERS[2]) * xp.reshape(weight[3], _CORNERS[3]))[..., None]
        leg = xp.sum(w * xp.asarray(self.leg_motor_pos)[i, j, k, q], axis=(0, 1, 2, 3))
        contact = xp.sum(w * xp.asarray(self.contact)[i, j, k, q], axis=(0, 1, 2, 3))
        return leg, contact

    def arrays(self) -> dict[str, np.ndarray]:
        """The reference as export arrays (``ref_*``)."""
        return {"ref_vx": np.asarray(self.vx), "ref_vy": np.asarray(self.vy), "ref_yaw": np.asarray(self.yaw),
                "ref_period": np.asarray(self.period), "ref_leg_motor_pos": np.asarray(self.leg_motor_pos),
                "ref_contact": np.asarray(self.contact)}

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray]) -> GaitReference:
        return cls(data["ref_vx"].astype(float), data["ref_vy"].astype(float), data["ref_yaw"].astype(float),
                   float(data["ref_period"]), data["ref_leg_motor_pos"].astype(float),
                   data["ref_contact"].astype(float))


_CORNERS = ((2, 1, 1, 1), (1, 2, 1, 1), (1, 1, 2, 1), (1, 1, 1, 2))
"""Broadcast shapes of the two bracketing indices (and weights) along vx, vy, yaw and phase."""


def leg_gain_scale(contact, stance, swing, xp: ModuleType = np):
    """Per-motor factor on the spec's P gains (walk-zmp's schedule): ``stance`` (n_motors,) while both feet are
    down, and for a foot whose reference stance flag is below 0.5 its leg's motors at ``swing[leg]`` (2, n_motors;
    0 = not that leg's motor)."""
    scale = xp.asarray(stance)
    swing = xp.asarray(swing)
    for leg in range(2):
        scale = xp.where((contact[leg] < 0.5) & (swing[leg] > 0), swing[leg], scale)
    return scale


def _swish(x: np.ndarray) -> np.ndarray:
    """x * sigmoid(x), with the sigmoid written through tanh so that no exponential overflows."""
    return x * (0.5 + 0.5 * np.tanh(0.5 * x))


MAX_POLICY_BYTES = 256 << 20
"""Largest exported policy file read, bytes (the shipped one is well under 1 MiB)."""

NETWORK_ARRAYS = ("obs_mean", "obs_std")
"""Arrays of an export that belong to the network (with ``layer{i}_kernel`` / ``layer{i}_bias``); the others are
the policy's metadata, which an ONNX export carries in its ``metadata_props``."""
ONNX_FORMAT = "toddlerbot-rl-onnx/1"
ONNX_INDEX = "toddlerbot.policy"
"""Metadata key of an ONNX export's index: JSON ``{"format", "arrays": {name: {"dtype", "shape"}}}``; each array
is stored under ``toddlerbot.<name>``: text scalars as they are, other arrays as the JSON of ``tolist()``."""
ONNX_INPUT, ONNX_OUTPUT = "obs", "action"
"""Names of an ONNX export's input (batch, n_obs) float32 raw observations and output (batch, n_actions) actions."""


def is_network_array(name: str) -> bool:
    return name in NETWORK_ARRAYS or (name.startswith("layer") and name.endswith(("_kernel", "_bias")))


def onnx_metadata(arrays: dict[str, np.ndarray]) -> dict[str, str]:
    """The metadata arrays of an export (everything but the network) as ONNX ``metadata_props`` strings; exact:
    `arrays_from_onnx_metadata` gives the same arrays back."""
    index, props = {}, {}
    for name, value in arrays.items():
        if is_network_array(name):
            continue
        value = np.asarray(value)
        if value.dtype.kind not in "Uifb":
            raise ValueError(f"{name}: dtype {value.dtype} cannot travel in ONNX metadata")
        index[name] = {"dtype": value.dtype.str, "shape": list(value.shape)}
        text = value.dtype.kind == "U" and value.ndim == 0
        props[f"toddlerbot.{name}"] = str(value) if text else json.dumps(value.tolist())
    return {ONNX_INDEX: json.dumps({"format": ONNX_FORMAT, "arrays": index}), **props}


def arrays_from_onnx_metadata(props: dict[str, str], path: Path) -> dict[str, np.ndarray]:
    """The metadata arrays an ONNX export carries (`onnx_metadata`), or a one-line `ToddlerbotError`."""
    if ONNX_INDEX not in props:
        raise ToddlerbotError(f"{path}: an ONNX model without toddlerbot policy metadata ({ONNX_INDEX}); export it "
                              "with `toddlerbot rl export --format onnx`")
    try:
        index = json.loads(props[ONNX_INDEX])
        if index.get("format") != ONNX_FORMAT:
            raise ValueError(f"format {index.get('format')!r}, expected {ONNX_FORMAT!r}")
        arrays = {}
        for name, spec in index["arrays"].items():
            raw = props[f"toddlerbot.{name}"]
            dtype = np.dtype(spec["dtype"])
            if dtype.kind not in "Uifb":
                raise ValueError(f"{name}: dtype {dtype} (expected text, integer, float or bool)")
            text = dtype.kind == "U" and not spec["shape"]
            arrays[name] = np.array(raw if text else json.loads(raw), dtype=dtype).reshape(spec["shape"])
        return arrays
    except KeyError as exc:
        raise ToddlerbotError(f"{path}: ONNX policy metadata misses {exc.args[0]!r}") from None
    except (ValueError, TypeError, AttributeError) as exc:
        raise ToddlerbotError(f"{path}: malformed ONNX policy metadata ({' '.join(str(exc).split())})") from None


def _check_size(path: Path) -> None:
    size = path.stat().st_size
    if size == 0:
        raise ToddlerbotError(f"{path}: empty file, not an exported RL policy")
    if size > MAX_POLICY_BYTES:
        raise ToddlerbotError(f"{path}: {size} bytes; an exported policy has at most {MAX_POLICY_BYTES} bytes")


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of an .npz file (no pickled objects), or a one-line `ToddlerbotError` naming the file."""
    import zipfile

    try:
        _check_size(path)
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise ToddlerbotError(f"{path}: a single .npy array, not an exported RL policy (.npz)")
        with loaded as data:
            return {key: data[key] for key in data.files}
    except ToddlerbotError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise ToddlerbotError(f"{path}: not a readable .npz file ({reason})") from None


class NumpyNetwork:
    """The actor MLP of an ``.npz`` export run with numpy: normalisation, swish hidden layers, the deterministic
    action (``tanh(mean)`` or ``clip(mean, -1, 1)``)."""

    def __init__(self, data: dict[str, np.ndarray], n_actions: int, distribution: str) -> None:
        n_layers = len([k for k in data if k.endswith("_kernel")])
        self.kernels = [data[f"layer{i}_kernel"].astype(np.float32) for i in range(n_layers)]
        self.biases = [data[f"layer{i}_bias"].astype(np.float32) for i in range(n_layers)]
        self.obs_mean = data["obs_mean"].astype(np.float32)
        self.obs_std = data["obs_std"].astype(np.float32)
        self.n_actions, self.distribution = n_actions, distribution

    def check(self, path: Path) -> None:
        """Shapes chain through the network, every number is finite, the output holds the actions."""
        if not self.kernels:
            raise ToddlerbotError(f"{path}: no network layers (layer0_kernel)")
        width = self.kernels[0].shape[0] if self.kernels[0].ndim == 2 else -1
        for i, (kernel, bias) in enumerate(zip(self.kernels, self.biases, strict=True)):
            if kernel.ndim != 2 or kernel.shape[0] != width or bias.shape != (kernel.shape[1],):
                raise ToddlerbotError(f"{path}: layer{i} has kernel {kernel.shape} and bias {bias.shape}; expected "
                                      f"({width}, n) and (n,)")
            width = kernel.shape[1]
        if width < self.n_actions:
            raise ToddlerbotError(f"{path}: network output {width} does not fit {self.n_actions} commanded motors")
        arrays = {"obs_mean": self.obs_mean, "obs_std": self.obs_std}
        arrays |= {f"layer{i}_kernel": k for i, k in enumerate(self.kernels)}
        arrays |= {f"layer{i}_bias": b for i, b in enumerate(self.biases)}
        for name, array in arrays.items():
            if not np.all(np.isfinite(array)):
                raise ToddlerbotError(f"{path}: {name} holds non-finite values (NaN or inf)")
        if self.obs_std.shape != self.obs_mean.shape or np.any(self.obs_std <= 0):
            raise ToddlerbotError(f"{path}: obs_std must be positive and shaped like obs_mean {self.obs_mean.shape}")

    @property
    def n_inputs(self) -> int:
        return self.kernels[0].shape[0] if self.obs_mean.shape == (self.kernels[0].shape[0],) else -1

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        x = (np.asarray(obs, dtype=np.float32) - self.obs_mean) / self.obs_std
        for i, (k, b) in enumerate(zip(self.kernels, self.biases, strict=True)):
            # einsum runs single-threaded: a threaded BLAS gemv stalls for milliseconds on a busy CPU
            x = np.einsum("i,ij->j", x, k) + b
            if i < len(self.kernels) - 1:
                x = _swish(x)
        mean = x[: self.n_actions]
        return np.tanh(mean) if self.distribution == "tanh_normal" else np.clip(mean, -1.0, 1.0)


class OnnxNetwork:
    """The graph of an ``.onnx`` export (raw observation -> deterministic action, normalisation included) run by
    onnxruntime on one CPU thread. onnxruntime is imported here only (extra ``[onnx]``)."""

    def __init__(self, path: Path) -> None:
        try:
            import onnxruntime as ort
        except ImportError:
            raise ToddlerbotError(f"{path}: running an ONNX policy needs onnxruntime, which is not installed "
                                  "(pip install 'toddlerbot[onnx]')") from None
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        options.log_severity_level = 3  # errors only
        try:
            self.session = ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own types for foreign or truncated bytes
            reason = " ".join(str(exc).split())[:300] or type(exc).__name__
            raise ToddlerbotError(f"{path}: not a readable ONNX model ({reason})") from None
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if [i.name for i in inputs] != [ONNX_INPUT] or [o.name for o in outputs] != [ONNX_OUTPUT]:
            raise ToddlerbotError(f"{path}: ONNX inputs {[i.name for i in inputs]} and outputs "
                                  f"{[o.name for o in outputs]}; an exported policy has [{ONNX_INPUT!r}] and "
                                  f"[{ONNX_OUTPUT!r}]")
        self.metadata = dict(self.session.get_modelmeta().custom_metadata_map)
        in_shape, out_shape = inputs[0].shape, outputs[0].shape
        self.n_inputs = in_shape[-1] if len(in_shape) == 2 and isinstance(in_shape[-1], int) else -1
        self.n_outputs = out_shape[-1] if len(out_shape) == 2 and isinstance(out_shape[-1], int) else -1

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        x = np.asarray(obs, dtype=np.float32).reshape(1, -1)
        return self.session.run(None, {ONNX_INPUT: x})[0][0]


class RLPolicyFile:
    """An exported policy (``.npz`` for numpy inference, or ``.onnx`` for onnxruntime) loaded and validated:
    finite numbers, consistent shapes, metadata that fits the network. Both formats carry the same metadata and
    go through the same checks; only `action`'s implementation differs."""

    def __init__(self, path: str | Path) -> None:
        path = Path(path)
        if not path.is_file():
            raise ToddlerbotError(f"{path}: exported policy not found (run `toddlerbot rl export`)")
        self.format = "onnx" if path.suffix.lower() == ".onnx" else "npz"
        if self.format == "onnx":
            _check_size(path)
            onnx_net = OnnxNetwork(path)
            data = arrays_from_onnx_metadata(onnx_net.metadata, path)
        else:
            data = _read_npz(path)
        self.metadata_arrays = {k: v for k, v in data.items() if not is_network_array(k)}
        """The export's arrays other than the network (what an ONNX export carries as metadata)."""
        try:
            self.home_motor_pos = data["home_motor_pos"].astype(float)
            self.leg_motor_index = data["leg_motor_index"].astype(int)
            self.action_motor_index = data["action_motor_index"].astype(int) if "action_motor_index" in data \
                else self.leg_motor_index
            """The motors the actions command, in action order."""
            self.motor_names = tuple(str(n) for n in data["motor_names"].reshape(-1))
            self.obs_config = ObsConfig.from_json(str(data["obs_config"]))
            self.meta = json.loads(str(data["meta"]))
            self.distribution = str(data["distribution"]) if "distribution" in data else "tanh_normal"
            self.action_std = data["action_std"].astype(np.float32) if "action_std" in data else None
            self.reference = GaitReference.from_arrays(data) if "ref_leg_motor_pos" in data else None
            """The gait reference of a residual policy (None: leg targets are home + scale x action)."""
            self.gain_scales = ((data["kp_stance_scale"].astype(float), data["kp_swing_scale"].astype(float))
                                if "kp_stance_scale" in data else None)
            """(stance, swing) P-gain factors of `leg_gain_scale` (None: the spec's gains)."""
            self.environment = str(self.meta.get("environment", "walk"))
            """The registered environment it was trained in."""
            self.motion = MotionTargets.from_arrays(data) if "motion_motor_targets" in data else None
            """The tracked motion's tables (a motion-tracking policy), else None."""
            network = onnx_net if self.format == "onnx" else \
                NumpyNetwork(data, self.n_actions, self.distribution)
        except KeyError as exc:
            raise ToddlerbotError(f"{path}: not an exported RL policy (missing {exc.args[0]!r})") from None
        except (ValueError, TypeError) as exc:  # wrong dtypes, malformed JSON or config fields
            raise ToddlerbotError(f"{path}: malformed exported policy ({' '.join(str(exc).split())})") from None
        if isinstance(network, NumpyNetwork):
            network.check(path)
        elif network.n_outputs != self.n_actions:
            raise ToddlerbotError(f"{path}: ONNX output width {network.n_outputs} does not fit "
                                  f"{self.n_actions} commanded motors")
        self._check_metadata(path)
        self.network = network
        """The action function: `NumpyNetwork` (its arrays: ``kernels``, ``biases``, ``obs_mean``, ``obs_std``)
        or `OnnxNetwork`."""
        self.path = path
        expected = self.n_inputs
        if network.n_inputs != expected:
            raise ToddlerbotError(f"{path}: network input {network.n_inputs} does not match the observation "
                                  f"config ({expected} = {self.obs_config.history} frames"
                                  f"{'' if self.motion is None else ' and the motion ahead'})")

    @property
    def n_actions(self) -> int:
        return len(self.action_motor_index)

    @property
    def n_inputs(self) -> int:
        """The actor observation's width: a walking policy's history of `obs_frame`s, or a tracking policy's
        (`toddlerbot.policies.track_observation.track_actor_obs`)."""
        n_motors = len(self.home_motor_pos)
        if self.motion is not None:
            return self.motion.actor_width(self.obs_config.history, n_motors)
        return self.obs_config.history * self.obs_config.frame_size(n_motors, self.n_actions)

    def for_robot(self, motor_names: tuple[str, ...], control_dt: float, environment: str, policy: str) -> None:
        """One line unless this file was trained in ``environment`` for these motors at this control period (s);
        ``policy``: the runtime policy asking."""
        if self.environment != environment:
            player = self.meta.get("runtime_policy", "another policy")
            raise ToddlerbotError(f"{self.path}: a policy of the {self.environment!r} environment; {policy} plays "
                                  f"{environment!r} policies (play it with --policy {player})")
        if tuple(self.motor_names) != tuple(motor_names):
            raise ToddlerbotError(f"{self.path}: trained for motors {self.motor_names[:3]}..., but the robot has "
                                  f"{tuple(motor_names)[:3]}... ({len(motor_names)} motors)")
        trained_dt = self.meta.get("ctrl_dt", control_dt)
        if abs(control_dt - trained_dt) > 1e-9:
            raise ToddlerbotError(f"{self.path}: trained at a {trained_dt} s control period; the robot runs at "
                                  f"{control_dt} s")

    def _check_metadata(self, path: Path) -> None:
        """Indices and names fit the motors, the home pose is finite."""
        n_motors = len(self.home_motor_pos)
        if len(self.motor_names) != n_motors or self.home_motor_pos.shape != (n_motors,):
            raise ToddlerbotError(f"{path}: {len(self.motor_names)} motor names and home pose "
                                  f"{self.home_motor_pos.shape} do not fit {self.n_actions} commanded of {n_motors} "
                                  "motors")
        for name, index in (("leg_motor_index", self.leg_motor_index), ("action_motor_index", self.action_motor_index)):
            if index.ndim != 1 or np.any((index < 0) | (index >= n_motors)):
                raise ToddlerbotError(f"{path}: {name} must hold motor indices in 0..{n_motors - 1}")
        if self.motion is not None:
            self.motion.check(path, n_motors)
        if not np.all(np.isfinite(self.home_motor_pos)):
            raise ToddlerbotError(f"{path}: home_motor_pos holds non-finite values (NaN or inf)")

    @property
    def kernels(self) -> list[np.ndarray]:
        return self._numpy_network().kernels

    @property
    def biases(self) -> list[np.ndarray]:
        return self._numpy_network().biases

    @property
    def obs_mean(self) -> np.ndarray:
        return self._numpy_network().obs_mean

    @property
    def obs_std(self) -> np.ndarray:
        return self._numpy_network().obs_std

    def _numpy_network(self) -> NumpyNetwork:
        if not isinstance(self.network, NumpyNetwork):
            raise ToddlerbotError(f"{self.path}: an ONNX export holds its weights in the graph, not as arrays")
        return self.network

    def action(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic action in [-1, 1]^n_actions (what the environment applies for the policy's mean) for one
        observation vector, normalised on the fly."""
        return self.network(obs)


class RLController:
    """Keeps the observation history and last action; turns robot state + command into motor targets. With a
    `Mirror`, the action is the mean of the policy's and its mirror image's (the policy run on the mirrored
    history, its action mirrored back): a symmetric controller from a policy that learned the two sides apart."""

    def __init__(self, policy: RLPolicyFile, mirror: Mirror | None = None) -> None:
        self.policy = policy
        self.cfg = policy.obs_config
        self.mirror = mirror
        self.reset()

    def reset(self) -> None:
        self.history: np.ndarray | None = None
        self.last_action = np.zeros(len(self.policy.leg_motor_index))

    def observation(self, t: float, command: np.ndarray, motor_pos: np.ndarray, motor_vel: np.ndarray,
                    gyro: np.ndarray, imu_quat: np.ndarray) -> np.ndarray:
        """Push a new frame (robot state at time t s since the gait started) and return the stacked history."""
        frame = obs_frame(t, np.asarray(command, float), motor_pos, self.policy.home_motor_pos, motor_vel,
                          self.last_action, gyro, gravity_in_frame(np.asarray(imu_quat, float)), self.cfg)
        if self.history is None:
            self.history = np.tile(frame, (self.cfg.history, 1))
        else:
            self.history = np.concatenate([frame[None], self.history[:-1]])
        return self.history.reshape(-1)

    def action(self) -> np.ndarray:
        """The action for the observation history (with a `Mirror`: the mean of the policy's and its mirror
        image's)."""
        action = self.policy.action(self.history.reshape(-1))
        if self.mirror is None:
            return action
        legs = self.policy.leg_motor_index
        mirrored = mirror_frame(self.history, self.mirror, legs).reshape(-1)
        return 0.5 * (action + mirror_leg_action(self.policy.action(mirrored), self.mirror, legs))

    def motor_targets(self, action: np.ndarray, command: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray | None]:
        """Motor position targets (rad, motor-id order) of an action at a command and time (s since the gait
        started): the home pose with the legs at the gait reference (residual policies) or home, plus the action's
        offsets; and the factor on each motor's P gain (None: the spec's gains)."""
        p = self.policy
        targets = p.home_motor_pos.copy()
        legs, contact = (targets[p.leg_motor_index], np.ones(2)) if p.reference is None else \
            p.reference.at(np.asarray(command, float), t)
        targets[p.leg_motor_index] = legs + self.cfg.action_scale * action
        return targets, None if p.gain_scales is None else leg_gain_scale(contact, *p.gain_scales)

    def step(self, t: float, command: np.ndarray, motor_pos: np.ndarray, motor_vel: np.ndarray,
             gyro: np.ndarray, imu_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """One 50 Hz control step: observation -> action -> (motor targets, P-gain factors or None)."""
        self.observation(t, command, motor_pos, motor_vel, gyro, imu_quat)
        action = self.action()
        self.last_action = action
        return self.motor_targets(action, command, t)
