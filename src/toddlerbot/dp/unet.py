"""Conditional 1-D U-Net over the action sequence, conditioned by FiLM on (diffusion step, observation features).

Input (B, horizon, action_dim), output the same shape (the predicted noise). Each residual block applies
``scale * h + shift`` per channel, with scale and shift a linear function of the conditioning vector.
"""

from __future__ import annotations

import itertools
import math

import torch
from torch import nn


def step_embedding(t: torch.Tensor, dim: int) -> torch.Tensor:
    """Sinusoidal embedding of diffusion steps (B,) -> (B, dim)."""
    half = dim // 2
    freq = torch.exp(-math.log(10000.0) * torch.arange(half, device=t.device) / max(half - 1, 1))
    angles = t.float()[:, None] * freq[None]
    return torch.cat([angles.sin(), angles.cos()], dim=-1)


class ConvNormAct(nn.Sequential):
    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, n_groups: int) -> None:
        super().__init__(nn.Conv1d(in_channels, out_channels, kernel_size, padding=kernel_size // 2),
                         nn.GroupNorm(n_groups, out_channels), nn.Mish())


class FiLMResidualBlock(nn.Module):
    """Two convolutions; between them the conditioning scales and shifts every channel (FiLM)."""

    def __init__(self, in_channels: int, out_channels: int, cond_dim: int, kernel_size: int, n_groups: int) -> None:
        super().__init__()
        self.conv1 = ConvNormAct(in_channels, out_channels, kernel_size, n_groups)
        self.conv2 = ConvNormAct(out_channels, out_channels, kernel_size, n_groups)
        self.film = nn.Sequential(nn.Mish(), nn.Linear(cond_dim, 2 * out_channels))
        self.skip = nn.Conv1d(in_channels, out_channels, 1) if in_channels != out_channels else nn.Identity()

    def forward(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        scale, shift = self.film(cond).unsqueeze(-1).chunk(2, dim=1)
        h = self.conv1(x) * scale + shift
        return self.conv2(h) + self.skip(x)


class ConditionalUnet1D(nn.Module):
    """U-Net over time with ``len(down_dims)`` levels; each level but the last halves the sequence."""

    def __init__(self, action_dim: int, cond_dim: int, down_dims: tuple[int, ...] = (64, 128, 256),
                 kernel_size: int = 5, n_groups: int = 8, step_embed_dim: int = 64) -> None:
        super().__init__()
        self.step_embed_dim = step_embed_dim
        self.step_mlp = nn.Sequential(nn.Linear(step_embed_dim, 4 * step_embed_dim), nn.Mish(),
                                      nn.Linear(4 * step_embed_dim, step_embed_dim))
        full_cond = step_embed_dim + cond_dim

        def block(i: int, o: int) -> FiLMResidualBlock:
            return FiLMResidualBlock(i, o, full_cond, kernel_size, n_groups)

        dims = (action_dim, *down_dims)
        self.down = nn.ModuleList()
        for level, (i, o) in enumerate(itertools.pairwise(dims)):
            last = level == len(down_dims) - 1
            self.down.append(nn.ModuleList([block(i, o), block(o, o),
                                            nn.Identity() if last else nn.Conv1d(o, o, 3, 2, 1)]))
        self.mid = nn.ModuleList([block(down_dims[-1], down_dims[-1]), block(down_dims[-1], down_dims[-1])])
        self.up = nn.ModuleList()
        for o, i in reversed(list(itertools.pairwise(down_dims))):
            self.up.append(nn.ModuleList([block(2 * i, o), block(o, o), nn.ConvTranspose1d(o, o, 4, 2, 1)]))
        self.head = nn.Sequential(ConvNormAct(down_dims[0], down_dims[0], kernel_size, n_groups),
                                  nn.Conv1d(down_dims[0], action_dim, 1))

    def forward(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """x (B, horizon, action_dim), t (B,) integer steps, cond (B, cond_dim) -> (B, horizon, action_dim)."""
        c = torch.cat([self.step_mlp(step_embedding(t, self.step_embed_dim)), cond], dim=-1)
        h = x.transpose(1, 2)
        skips = []
        for first, second, downsample in self.down:
            h = second(first(h, c), c)
            skips.append(h)
            h = downsample(h)
        for b in self.mid:
            h = b(h, c)
        for first, second, upsample in self.up:
            h = second(first(torch.cat([h, skips.pop()], dim=1), c), c)
            h = upsample(h)
        return self.head(h).transpose(1, 2)
