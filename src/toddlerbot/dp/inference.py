"""A loaded policy as the ``infer`` callable of `ChunkPolicyRunner`: numpy observation history -> numpy chunk."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch

from toddlerbot.dp.checkpoint import load_policy
from toddlerbot.dp.policy import IMAGE, STATE, DiffusionPolicy


class PolicyInference:
    """Runs ``policy.sample`` on one observation history; keeps the duration of the last call."""

    def __init__(self, policy: DiffusionPolicy, seed: int = 0) -> None:
        self.policy = policy.eval()
        self.generator = torch.Generator().manual_seed(seed)
        self.last_seconds = float("nan")

    @classmethod
    def from_checkpoint(cls, path: str | Path, seed: int = 0) -> PolicyInference:
        return cls(load_policy(path), seed)

    def __call__(self, history: dict[str, np.ndarray]) -> np.ndarray:
        """``observation.state`` (n_obs, D) rad and ``observation.images.head`` (n_obs, 3, H, W) uint8 -> chunk
        (horizon, A) in the dataset's action units."""
        start = time.perf_counter()
        device = next(self.policy.parameters()).device
        batch = {STATE: torch.as_tensor(np.asarray(history[STATE], np.float32), device=device)[None]}
        if self.policy.config.uses_images:
            batch[IMAGE] = torch.as_tensor(np.asarray(history[IMAGE]), device=device)[None]
        with torch.inference_mode():
            chunk = self.policy.sample(batch, self.generator)[0].cpu().numpy()
        self.last_seconds = time.perf_counter() - start
        return chunk
