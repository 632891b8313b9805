"""The diffusion policy network: observation encoder + conditional U-Net + noise schedule + normalisers.

Batches are dicts of tensors, the window dataset's keys: ``observation.state`` (B, n_obs, state_dim) float32 in
dataset units, ``observation.images.head`` (B, n_obs, 3, H, W) uint8, ``action`` (B, horizon, action_dim) float32,
``action_is_pad`` (B, horizon) bool. All scaling happens inside this module, identically in `loss` and `sample`.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from toddlerbot.dp.config import DPConfig
from toddlerbot.dp.encoders import ResNet18Encoder, SmallCNNEncoder
from toddlerbot.dp.normalize import MinMaxNormalizer, crop_images, crop_offsets, images_to_unit
from toddlerbot.dp.scheduler import NoiseSchedule
from toddlerbot.dp.unet import ConditionalUnet1D

STATE, IMAGE, ACTION, ACTION_PAD = "observation.state", "observation.images.head", "action", "action_is_pad"


def normal_noise(shape: torch.Size | tuple[int, ...], generator: torch.Generator | None,
                  device: torch.device) -> torch.Tensor:
    """Standard normal noise on ``device``, drawn from ``generator`` on its own device (a seeded CPU generator keeps
    validation and inference noise the same whether the network runs on the CPU or a GPU)."""
    source = generator.device if generator is not None else device
    return torch.randn(shape, generator=generator, device=source).to(device)


@dataclass(frozen=True)
class TrainingDraws:
    """The random draws of one training step for b windows: the noise added to each action chunk (b, horizon,
    action_dim), its diffusion step (b,) and, with random crops, each image's crop offsets (b, n_obs, 2). Drawn for
    the whole (global) batch, so data-parallel processes that take their `part` use the draws one process would."""

    noise: torch.Tensor
    steps: torch.Tensor
    crops: torch.Tensor | None = None

    def part(self, rows: slice) -> TrainingDraws:
        return TrainingDraws(self.noise[rows], self.steps[rows], None if self.crops is None else self.crops[rows])


def build_encoder(config: DPConfig) -> nn.Module | None:
    if config.encoder == "resnet18":
        return ResNet18Encoder(config.image_feature_dim)
    if config.encoder == "small_cnn":
        return SmallCNNEncoder(config.small_cnn_channels, config.image_feature_dim)
    return None


class DiffusionPolicy(nn.Module):
    """Predicts a ``horizon``-step action chunk from ``n_obs_steps`` observations (state and head image)."""

    def __init__(self, config: DPConfig) -> None:
        super().__init__()
        if config.state_dim < 1 or config.action_dim < 1:
            raise ValueError("config.state_dim and config.action_dim must be set (DPConfig.with_dims)")
        self.config = config
        self.state_norm = MinMaxNormalizer(config.state_dim)
        self.action_norm = MinMaxNormalizer(config.action_dim)
        self.encoder = build_encoder(config)
        per_step = config.state_dim + (config.image_feature_dim if config.uses_images else 0)
        self.unet = ConditionalUnet1D(config.action_dim, per_step * config.n_obs_steps, config.down_dims,
                                      config.kernel_size, config.n_groups, config.step_embed_dim)
        self.schedule = NoiseSchedule(config.train_timesteps, config.beta_schedule, config.clip_sample,
                                      config.prediction)
        self.binary_dims = [config.action_names.index(name) for name in config.binary_actions]

    def condition(self, batch: dict[str, torch.Tensor], crops: torch.Tensor | None = None) -> torch.Tensor:
        """Observation features (B, n_obs * (state_dim [+ image_feature_dim])): normalised state, encoded images
        (``crops`` (B, n_obs, 2): the training crops' offsets, else drawn here)."""
        state = batch[STATE]
        n = self.config.n_obs_steps
        if state.ndim != 3 or state.shape[1:] != (n, self.config.state_dim):
            raise ValueError(f"{STATE}: shape {tuple(state.shape)}, expected (B, {n}, {self.config.state_dim})")
        features = [self.state_norm.normalize(state.float())]
        if self.encoder is not None:
            images = batch[IMAGE]
            b = images.shape[0]
            flat = images_to_unit(images.reshape(b * n, *images.shape[2:]))
            flat = crop_images(flat, self.config.crop_size, random=self.training,
                               offsets=None if crops is None else crops.reshape(b * n, 2))
            features.append(self.encoder(flat).reshape(b, n, -1))
        return torch.cat(features, dim=-1).flatten(1)

    def draw(self, batch: dict[str, torch.Tensor], size: int | None = None,
             generator: torch.Generator | None = None) -> TrainingDraws:
        """The random draws of a training step for ``size`` windows shaped like ``batch``'s (default: its own
        size): noise and steps from ``generator`` (else the device's global one), crop offsets (in training, with
        ``crop_size``) from torch's global CPU generator."""
        cfg = self.config
        b = batch[ACTION].shape[0] if size is None else size
        device = batch[ACTION].device
        noise = normal_noise((b, cfg.horizon, cfg.action_dim), generator, device)
        source = generator.device if generator is not None else device
        steps = torch.randint(0, cfg.train_timesteps, (b,), generator=generator, device=source).to(device)
        crops = None
        if self.training and self.encoder is not None and cfg.crop_size > 0:
            height, width = batch[IMAGE].shape[-2:]
            if (height, width) != (cfg.crop_size, cfg.crop_size):
                crops = crop_offsets(b * cfg.n_obs_steps, height, width, cfg.crop_size).view(b, cfg.n_obs_steps, 2)
        return TrainingDraws(noise, steps, crops)

    def forward(self, batch: dict[str, torch.Tensor], draws: TrainingDraws) -> tuple[torch.Tensor, torch.Tensor]:
        """The denoising loss's terms: the squared error (of the noise or the clean sample, ``config.prediction``)
        summed over the non-padded actions, and their count (a data-parallel loss divides by the global count)."""
        x0 = self.action_norm.normalize(batch[ACTION].float())
        pred = self.unet(self.schedule.add_noise(x0, draws.noise, draws.steps), draws.steps,
                         self.condition(batch, draws.crops))
        err = F.mse_loss(pred, self.schedule.training_target(x0, draws.noise), reduction="none")
        if ACTION_PAD in batch:
            mask = ~batch[ACTION_PAD].to(torch.bool)
        else:
            mask = torch.ones(x0.shape[:2], dtype=torch.bool, device=x0.device)
        weights = mask.unsqueeze(-1).expand_as(err).float()
        return (err * weights).sum(), weights.sum()

    def loss(self, batch: dict[str, torch.Tensor], generator: torch.Generator | None = None) -> torch.Tensor:
        """Denoising MSE (of the noise or the clean sample, ``config.prediction``) over the non-padded actions."""
        total, count = self(batch, self.draw(batch, generator=generator))
        return total / count.clamp(min=1.0)

    @torch.no_grad()
    def sample(self, batch: dict[str, torch.Tensor], generator: torch.Generator | None = None,
               sampler: str | None = None, steps: int | None = None) -> torch.Tensor:
        """Denoise an action chunk (B, horizon, action_dim) in dataset units (``inference_steps`` of ``sampler``)."""
        cfg = self.config
        sampler = sampler or cfg.sampler
        cond = self.condition(batch)
        b = cond.shape[0]
        x = normal_noise((b, cfg.horizon, cfg.action_dim), generator, cond.device)
        timesteps = self.schedule.inference_timesteps(steps or cfg.inference_steps)
        for k, t in enumerate(timesteps):
            s = timesteps[k + 1] if k + 1 < len(timesteps) else -1
            output = self.unet(x, torch.full((b,), t, device=cond.device), cond)
            if sampler == "ddim":
                x = self.schedule.ddim_step(x, output, t, s)
            else:
                noise = normal_noise(x.shape, generator, x.device) if s >= 0 else None
                x = self.schedule.ddpm_step(x, output, t, s, noise)
        if self.binary_dims:  # open or closed, as demonstrated (config.binary_actions)
            x[..., self.binary_dims] = torch.where(x[..., self.binary_dims] > 0, 1.0, -1.0)
        return self.action_norm.unnormalize(x)
