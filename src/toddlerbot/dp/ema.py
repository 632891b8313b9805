"""Exponential moving average of a network's weights (the copy used for validation and inference)."""

from __future__ import annotations

import copy

import torch
from torch import nn


class EMA:
    """``ema = d * ema + (1 - d) * weights`` after each optimiser step, ``d = min(decay, (1 + n) / (10 + n))``.

    The warm-up ``(1 + n) / (10 + n)`` after n updates keeps early averages from clinging to the random
    initialisation in short runs. Buffers (the normalisers' ranges) are copied as they are.
    """

    def __init__(self, model: nn.Module, decay: float) -> None:
        if not 0.0 <= decay < 1.0:
            raise ValueError(f"EMA decay {decay} (expected 0 <= decay < 1)")
        self.decay = decay
        self.model = copy.deepcopy(model).eval().requires_grad_(False)
        self.updates = 0

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        self.updates += 1
        decay = min(self.decay, (1 + self.updates) / (10 + self.updates))
        # one fused update for all parameters (a kernel per tensor would dominate a GPU step)
        torch._foreach_lerp_(list(self.model.parameters()), [p.detach() for p in model.parameters()], 1.0 - decay)
        for ema_b, b in zip(self.model.buffers(), model.buffers()):
            ema_b.copy_(b)
