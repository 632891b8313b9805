"""Diffusion-policy configuration: plain data saved as JSON inside every checkpoint so it rebuilds its network."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields, replace

from toddlerbot.errors import ToddlerbotError
from toddlerbot.tasks.space import POLICY_HZ

ENCODERS = ("resnet18", "small_cnn", "none")
SAMPLERS = ("ddpm", "ddim")


class DPConfigError(ToddlerbotError):
    """A diffusion-policy configuration (or the one inside a checkpoint) is malformed."""


@dataclass(frozen=True)
class DPConfig:
    """Network, schedule and training settings. Defaults are the appendix's (8.12) where it gives them."""

    state_dim: int = 0
    """Length of ``observation.state`` (joint angles, rad, and gripper; set from the dataset)."""
    action_dim: int = 0
    """Length of ``action`` (joint targets; set from the dataset)."""
    state_names: tuple[str, ...] = ()
    """Name of each state dimension (the dataset's joint names), so a runtime can map the policy to robot joints."""
    action_names: tuple[str, ...] = ()
    """Name of each action dimension."""
    binary_actions: tuple[str, ...] = ()
    """Action dimensions the demonstrations only open or close (a gripper): each sampled value snaps to the nearer
    end of the demonstrated range (the normalised sign), so a learned close commands the demonstrations' closed
    value instead of landing just short of it, where a check of "commanded closed" fails (docs/manipulation.md)."""
    n_obs_steps: int = 2
    """Observation history, at the policy rate."""
    horizon: int = 16
    """Predicted actions per inference, at the policy rate."""
    latency_drop: int = 3
    """Leading actions skipped at execution (their time has passed while inference ran)."""
    n_action_steps: int = 5
    """Actions executed per inference, after the dropped ones."""
    policy_hz: float = float(POLICY_HZ)
    """Rate of observations and predicted actions, Hz."""
    image_size: int = 96
    """Side of the square head-camera image, pixels."""
    encoder: str = "small_cnn"
    """Image encoder: ``resnet18`` (GroupNorm; appendix), ``small_cnn`` (CPU training) or ``none`` (state only)."""
    crop_size: int = 0
    """Random crop of this side in training and the centre crop at inference (diffusion policy's augmentation);
    0 keeps the whole image."""
    image_feature_dim: int = 64
    """Image feature length per observation step."""
    small_cnn_channels: tuple[int, ...] = (16, 32, 64, 64)
    """Channels of the small CNN's stride-2 convolutions."""
    down_dims: tuple[int, ...] = (64, 128, 256)
    """U-Net channels per resolution level."""
    kernel_size: int = 5
    """U-Net temporal convolution kernel, in action steps."""
    n_groups: int = 8
    """GroupNorm groups in the U-Net."""
    step_embed_dim: int = 64
    """Sinusoidal diffusion-step embedding size."""
    train_timesteps: int = 100
    """Diffusion steps in training (appendix: 100)."""
    inference_steps: int = 3
    """Denoising steps at inference (appendix: 3 DDPM steps)."""
    prediction: str = "sample"
    """What the U-Net predicts: ``sample`` (the clean action chunk) or ``epsilon`` (the noise, as in DDPM). With
    only 3 inference steps an epsilon error is amplified by ``sqrt(1 - alpha_bar) / sqrt(alpha_bar)`` (1.8 at step
    66): on a fixed 1-D chunk a tiny U-Net reached 0.006 max error after 300 steps predicting the sample and
    0.27-0.55 predicting the noise (docs/manipulation.md)."""
    sampler: str = "ddpm"
    """Inference sampler: ``ddpm`` (stochastic) or ``ddim`` (deterministic)."""
    beta_schedule: str = "squaredcos_cap_v2"
    """Noise schedule: ``squaredcos_cap_v2`` (cosine) or ``linear``."""
    clip_sample: float = 1.0
    """Predicted clean actions are clipped to +-this (normalised units); 0 disables."""
    batch_size: int = 64
    learning_rate: float = 1e-4
    weight_decay: float = 1e-6
    ema_decay: float = 0.995
    """Exponential moving average of the weights used for inference and validation."""
    val_fraction: float = 0.1
    """Fraction of episodes (not windows) held out for validation."""
    seed: int = 0

    def __post_init__(self) -> None:
        problems = []
        if self.encoder not in ENCODERS:
            problems.append(f"encoder {self.encoder!r} (expected one of {', '.join(ENCODERS)})")
        if self.sampler not in SAMPLERS:
            problems.append(f"sampler {self.sampler!r} (expected one of {', '.join(SAMPLERS)})")
        if self.prediction not in ("epsilon", "sample"):
            problems.append(f"prediction {self.prediction!r} (expected epsilon or sample)")
        if self.beta_schedule not in ("squaredcos_cap_v2", "linear"):
            problems.append(f"beta_schedule {self.beta_schedule!r} (expected squaredcos_cap_v2 or linear)")
        if not 1 <= self.inference_steps <= self.train_timesteps:
            problems.append(f"inference_steps {self.inference_steps} (expected 1..train_timesteps)")
        if self.latency_drop + self.n_action_steps > self.horizon:
            problems.append(f"latency_drop + n_action_steps = {self.latency_drop + self.n_action_steps} "
                            f"> horizon {self.horizon}")
        stride = 2 ** (len(self.down_dims) - 1)
        if self.horizon % stride:
            problems.append(f"horizon {self.horizon} (must be divisible by {stride} for {len(self.down_dims)} "
                            "U-Net levels)")
        if any(d % self.n_groups for d in self.down_dims):
            problems.append(f"down_dims {self.down_dims} (each must be divisible by n_groups {self.n_groups})")
        if not 0 <= self.crop_size <= self.image_size:
            problems.append(f"crop_size {self.crop_size} (expected 0..image_size {self.image_size})")
        for names, dim in ((self.state_names, self.state_dim), (self.action_names, self.action_dim)):
            if names and len(names) != dim:
                problems.append(f"{len(names)} names for {dim} dimensions")
        unknown = [n for n in self.binary_actions if self.action_names and n not in self.action_names]
        unnamed = self.binary_actions and self.action_dim and not self.action_names
        if unknown or unnamed or len(set(self.binary_actions)) != len(self.binary_actions):
            problems.append(f"binary_actions {list(self.binary_actions)} (expected distinct action names, of "
                            f"{', '.join(self.action_names)})")
        if self.n_obs_steps < 1 or self.state_dim < 0 or self.action_dim < 0:
            problems.append("n_obs_steps >= 1, state_dim >= 0 and action_dim >= 0 expected")
        if not 0.0 <= self.val_fraction < 1.0:
            problems.append(f"val_fraction {self.val_fraction} (expected 0 <= f < 1)")
        if problems:
            raise DPConfigError("diffusion-policy config: " + "; ".join(problems))

    @property
    def uses_images(self) -> bool:
        return self.encoder != "none"

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str, source: str = "config") -> DPConfig:
        """Parse a config written by `to_json`; unknown or mistyped fields name the source."""
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as exc:
            raise DPConfigError(f"{source}: not JSON ({exc})") from exc
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(raw) - known)
        if unknown:
            raise DPConfigError(f"{source}: unknown config field(s) {', '.join(unknown)}")
        for name in ("small_cnn_channels", "down_dims", "state_names", "action_names", "binary_actions"):
            if name in raw:
                raw[name] = tuple(raw[name])
        try:
            return cls(**raw)
        except TypeError as exc:
            raise DPConfigError(f"{source}: {exc}") from exc

    def with_dims(self, state_dim: int, action_dim: int, state_names: tuple[str, ...] = (),
                  action_names: tuple[str, ...] = ()) -> DPConfig:
        return replace(self, state_dim=state_dim, action_dim=action_dim, state_names=tuple(state_names),
                       action_names=tuple(action_names))


SMALL = DPConfig(down_dims=(32, 64, 128))
"""The CPU configuration: small CNN at 96 px, U-Net (32, 64, 128) (inference within 50 ms on one core)."""
APPENDIX = DPConfig(encoder="resnet18", image_feature_dim=512, down_dims=(256, 512, 1024), crop_size=84)
"""The appendix-size configuration: ResNet-18 (GroupNorm) image encoder on 84x84 crops, U-Net (256, 512, 1024)."""
TINY = DPConfig(encoder="small_cnn", small_cnn_channels=(8, 16), image_feature_dim=16, down_dims=(16, 32),
                step_embed_dim=16, batch_size=16, learning_rate=1e-3, ema_decay=0.9)
"""A configuration small enough for tests (seconds of CPU)."""
PRESETS = {"small": SMALL, "appendix": APPENDIX, "tiny": TINY}
