"""Numpy-only inference of an exported RL walking policy (no JAX: this runs on the robot's CPU at 50 Hz).

An exported policy is one ``.npz`` file holding

* ``layer{i}_kernel`` / ``layer{i}_bias``: the actor MLP (swish hidden activations, linear output),
* ``distribution``: ``normal`` (the output is the mean of a Gaussian whose samples the environment clips to
  [-1, 1], so the deterministic action is ``clip(mean, -1, 1)``; ``action_std`` holds its standard deviation)
  or, in files without this entry, ``tanh_normal`` (the output's first half is the pre-tanh mean; the
  deterministic action is ``tanh(mean)``),
* ``obs_mean`` / ``obs_std``: the observation normalisation learned during training,
* ``home_motor_pos``: motor angles of the home pose (rad, motor-id order), ``leg_motor_index``: the 12
  commanded motors, ``motor_names``,
* ``obs_config``: the `ObsConfig` as JSON, ``meta``: training metadata as JSON,
* for a residual policy (leg targets = gait reference + ``action_scale`` x action), the `GaitReference` arrays
  (``ref_vx``, ``ref_vy``, ``ref_yaw``, ``ref_period``, ``ref_leg_motor_pos``, ``ref_contact``), and for a policy
  trained with walk-zmp's leg gain schedule, ``kp_stance_scale`` / ``kp_swing_scale`` (`leg_gain_scale`).

`obs_frame` is the single definition of one observation frame; the MJX environment builds its frames with the
same function (``xp=jax.numpy``), which is what makes training and deployment agree.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from types import ModuleType

import numpy as np

from toddlerbot.errors import ToddlerbotError

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
        """Features per frame: phase 2, command 3, motor angles relative to home and motor speeds (n_motors
        each), last action (n_actions, one per leg motor), gyro 3, gravity direction in the IMU frame 3."""
        return 2 + 3 + 2 * n_motors + n_actions + 3 + 3

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> ObsConfig:
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in json.loads(text).items() if k in names})


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


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of an .npz file (no pickled objects), or a one-line `ToddlerbotError` naming the file."""
    import zipfile

    try:
        size = path.stat().st_size
        if size == 0:
            raise ToddlerbotError(f"{path}: empty file, not an exported RL policy")
        if size > MAX_POLICY_BYTES:
            raise ToddlerbotError(f"{path}: {size} bytes; an exported policy has at most {MAX_POLICY_BYTES} bytes")
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


def _check_policy_arrays(policy: RLPolicyFile, path: Path) -> None:
    """Shapes chain through the network, every number is finite, indices and names fit the motors."""
    if not policy.kernels:
        raise ToddlerbotError(f"{path}: no network layers (layer0_kernel)")
    width = policy.kernels[0].shape[0] if policy.kernels[0].ndim == 2 else -1
    for i, (kernel, bias) in enumerate(zip(policy.kernels, policy.biases, strict=True)):
        if kernel.ndim != 2 or kernel.shape[0] != width or bias.shape != (kernel.shape[1],):
            raise ToddlerbotError(f"{path}: layer{i} has kernel {kernel.shape} and bias {bias.shape}; expected "
                                  f"({width}, n) and (n,)")
        width = kernel.shape[1]
    n_motors, n_legs = len(policy.home_motor_pos), len(policy.leg_motor_index)
    if width < n_legs or len(policy.motor_names) != n_motors or policy.home_motor_pos.shape != (n_motors,):
        raise ToddlerbotError(f"{path}: network output {width}, {len(policy.motor_names)} motor names and home pose "
                              f"{policy.home_motor_pos.shape} do not fit {n_legs} commanded of {n_motors} motors")
    if policy.leg_motor_index.ndim != 1 or np.any((policy.leg_motor_index < 0) | (policy.leg_motor_index >= n_motors)):
        raise ToddlerbotError(f"{path}: leg_motor_index must hold motor indices in 0..{n_motors - 1}")
    arrays = {"obs_mean": policy.obs_mean, "obs_std": policy.obs_std, "home_motor_pos": policy.home_motor_pos}
    arrays |= {f"layer{i}_kernel": k for i, k in enumerate(policy.kernels)}
    arrays |= {f"layer{i}_bias": b for i, b in enumerate(policy.biases)}
    for name, array in arrays.items():
        if not np.all(np.isfinite(array)):
            raise ToddlerbotError(f"{path}: {name} holds non-finite values (NaN or inf)")
    if policy.obs_std.shape != policy.obs_mean.shape or np.any(policy.obs_std <= 0):
        raise ToddlerbotError(f"{path}: obs_std must be positive and shaped like obs_mean {policy.obs_mean.shape}")


class RLPolicyFile:
    """An exported policy loaded for numpy inference (validated: finite numbers, consistent shapes)."""

    def __init__(self, path: str | Path) -> None:
        path = Path(path)
        if not path.is_file():
            raise ToddlerbotError(f"{path}: exported policy not found (run `toddlerbot rl export`)")
        data = _read_npz(path)
        try:
            n_layers = len([k for k in data if k.endswith("_kernel")])
            self.kernels = [data[f"layer{i}_kernel"].astype(np.float32) for i in range(n_layers)]
            self.biases = [data[f"layer{i}_bias"].astype(np.float32) for i in range(n_layers)]
            self.obs_mean = data["obs_mean"].astype(np.float32)
            self.obs_std = data["obs_std"].astype(np.float32)
            self.home_motor_pos = data["home_motor_pos"].astype(float)
            self.leg_motor_index = data["leg_motor_index"].astype(int)
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
        except KeyError as exc:
            raise ToddlerbotError(f"{path}: not an exported RL policy (missing {exc.args[0]!r})") from None
        except (ValueError, TypeError) as exc:  # wrong dtypes, malformed JSON or config fields
            raise ToddlerbotError(f"{path}: malformed exported policy ({' '.join(str(exc).split())})") from None
        _check_policy_arrays(self, path)
        self.path = path
        frame = self.obs_config.frame_size(len(self.home_motor_pos), len(self.leg_motor_index))
        expected = self.obs_config.history * frame
        if self.kernels[0].shape[0] != expected or self.obs_mean.shape != (expected,):
            raise ToddlerbotError(f"{path}: network input {self.kernels[0].shape[0]} does not match the observation "
                                  f"config ({expected} = {self.obs_config.history} frames)")

    def action(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic action in [-1, 1]^12 (what the environment applies for the policy's mean) for one
        observation vector, normalised on the fly."""
        x = (np.asarray(obs, dtype=np.float32) - self.obs_mean) / self.obs_std
        for i, (k, b) in enumerate(zip(self.kernels, self.biases, strict=True)):
            # einsum runs single-threaded: a threaded BLAS gemv stalls for milliseconds on a busy CPU
            x = np.einsum("i,ij->j", x, k) + b
            if i < len(self.kernels) - 1:
                x = _swish(x)
        mean = x[: len(self.leg_motor_index)]
        return np.tanh(mean) if self.distribution == "tanh_normal" else np.clip(mean, -1.0, 1.0)


class RLController:
    """Keeps the observation history and last action; turns robot state + command into motor targets."""

    def __init__(self, policy: RLPolicyFile) -> None:
        self.policy = policy
        self.cfg = policy.obs_config
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
        obs = self.observation(t, command, motor_pos, motor_vel, gyro, imu_quat)
        action = self.policy.action(obs)
        self.last_action = action
        return self.motor_targets(action, command, t)
