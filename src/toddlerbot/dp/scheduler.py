"""DDPM noise schedule (training forward process) with DDPM and DDIM samplers on a subset of steps.

Notation: ``alpha_bar[t] = prod_{i<=t} (1 - beta[i])`` for t = 0..T-1; the forward process is
``x_t = sqrt(alpha_bar[t]) x_0 + sqrt(1 - alpha_bar[t]) eps``. Sampling with K < T steps visits
``t_k = T - 1 - k * (T // K)`` ... and jumps from t to s < t with the marginal ratio ``alpha_bar[t] / alpha_bar[s]``
(``alpha_bar = 1`` below step 0), so 3 DDPM steps of a 100-step schedule are an exact DDPM on the coarse chain.
"""

from __future__ import annotations

import math

import torch


def cosine_betas(n: int, max_beta: float = 0.999) -> torch.Tensor:
    """Betas of the squared-cosine schedule (Nichol & Dhariwal 2021), float64."""
    def alpha_bar(u: float) -> float:
        return math.cos((u + 0.008) / 1.008 * math.pi / 2) ** 2
    return torch.tensor([min(1 - alpha_bar((i + 1) / n) / alpha_bar(i / n), max_beta) for i in range(n)],
                        dtype=torch.float64)


class NoiseSchedule:
    """The noise schedule of ``train_timesteps`` steps and a sampler (``ddpm`` or ``ddim``) over ``inference_steps``."""

    def __init__(self, train_timesteps: int = 100, beta_schedule: str = "squaredcos_cap_v2",
                 clip_sample: float = 1.0, prediction: str = "epsilon") -> None:
        """``prediction``: what the network outputs, ``epsilon`` (noise) or ``sample`` (clean x_0)."""
        if beta_schedule == "squaredcos_cap_v2":
            betas = cosine_betas(train_timesteps)
        elif beta_schedule == "linear":
            betas = torch.linspace(1e-4, 2e-2, train_timesteps, dtype=torch.float64)
        else:
            raise ValueError(f"unknown beta schedule {beta_schedule!r}")
        self.train_timesteps = train_timesteps
        self.betas = betas
        self.alpha_bar = torch.cumprod(1 - betas, 0)
        self.clip_sample = clip_sample
        self.prediction = prediction

    def inference_timesteps(self, steps: int) -> list[int]:
        """Descending steps visited by a ``steps``-step sampler (e.g. 66, 33, 0 for 3 of 100)."""
        stride = self.train_timesteps // steps
        return [t * stride for t in reversed(range(steps))]

    def _alpha_bar(self, t: torch.Tensor) -> torch.Tensor:
        """alpha_bar at integer steps (tensor), 1 for t < 0, as float32."""
        padded = torch.cat([torch.ones(1, dtype=torch.float64), self.alpha_bar]).to(torch.float32)
        return padded.to(t.device)[t.long() + 1]

    def add_noise(self, x0: torch.Tensor, noise: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """Forward process: x_t for a batch of clean samples (B, …) at steps t (B,)."""
        ab = self._alpha_bar(t).view(-1, *([1] * (x0.ndim - 1)))
        return ab.sqrt() * x0 + (1 - ab).sqrt() * noise

    def training_target(self, x0: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """What the network is trained to output."""
        return noise if self.prediction == "epsilon" else x0

    def predict_x0(self, x_t: torch.Tensor, output: torch.Tensor, t: int) -> torch.Tensor:
        """Clean sample implied by the network output at step t, clipped to +-clip_sample when enabled."""
        if self.prediction == "epsilon":
            ab = self._alpha_bar(torch.tensor([t]))[0]
            x0 = (x_t - (1 - ab).sqrt() * output) / ab.sqrt()
        else:
            x0 = output
        return x0.clamp(-self.clip_sample, self.clip_sample) if self.clip_sample > 0 else x0

    def ddpm_step(self, x_t: torch.Tensor, output: torch.Tensor, t: int, s: int,
                  noise: torch.Tensor | None) -> torch.Tensor:
        """One DDPM posterior sample x_s ~ q(x_s | x_t, x0_hat) for s < t (s = -1: the final, noise-free step)."""
        ab_t, ab_s = self._alpha_bar(torch.tensor([t, s]))
        alpha_ts = ab_t / ab_s
        beta_ts = 1 - alpha_ts
        x0 = self.predict_x0(x_t, output, t)
        mean = (ab_s.sqrt() * beta_ts / (1 - ab_t)) * x0 + (alpha_ts.sqrt() * (1 - ab_s) / (1 - ab_t)) * x_t
        if s < 0 or noise is None:
            return mean
        variance = ((1 - ab_s) / (1 - ab_t) * beta_ts).clamp(min=1e-20)
        return mean + variance.sqrt() * noise

    def ddim_step(self, x_t: torch.Tensor, output: torch.Tensor, t: int, s: int) -> torch.Tensor:
        """One deterministic DDIM step (eta = 0) from t to s < t."""
        ab_t, ab_s = self._alpha_bar(torch.tensor([t, s]))
        x0 = self.predict_x0(x_t, output, t)
        eps_used = (x_t - ab_t.sqrt() * x0) / (1 - ab_t).sqrt()  # consistent with the clipped x0
        return ab_s.sqrt() * x0 + (1 - ab_s).sqrt() * eps_used
