"""Min-max normalisation of state and action to [-1, 1], and the ONE image conversion used in training and inference.

The ranges live in module buffers, so they are saved inside the checkpoint's state dict and the same numbers scale
the data in training and at inference.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from toddlerbot.errors import ToddlerbotError

MIN_HALF_RANGE = 1e-4
"""A dimension whose range is narrower than twice this (a constant gripper) is centred, not scaled up."""


class ImageFormatError(ToddlerbotError):
    """An image batch is not the uint8 (…, 3, H, W) the policy takes."""


def images_to_unit(images: torch.Tensor) -> torch.Tensor:
    """uint8 images (…, 3, H, W), 0-255 -> float32 in [0, 1]. The only place images are scaled.

    Taking uint8 only is deliberate: a float image may already be scaled, and scaling twice (or not at all) is the
    train/inference mismatch this function exists to prevent.
    """
    if images.dtype != torch.uint8:
        raise ImageFormatError(f"images must be uint8 0-255 (…, 3, H, W), got dtype {images.dtype}")
    if images.ndim < 3 or images.shape[-3] != 3:
        raise ImageFormatError(f"images must be (…, 3, H, W), got shape {tuple(images.shape)}")
    return images.to(torch.float32) / 255.0


class MinMaxNormalizer(nn.Module):
    """Maps each dimension's [min, max] to [-1, 1]: ``y = (x - centre) / half_range``."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.register_buffer("centre", torch.zeros(dim))
        self.register_buffer("half_range", torch.ones(dim))

    def fit(self, minimum: np.ndarray | torch.Tensor, maximum: np.ndarray | torch.Tensor) -> MinMaxNormalizer:
        """Set the range from per-dimension minima and maxima (same units as the data)."""
        lo = torch.as_tensor(np.asarray(minimum, dtype=np.float32))
        hi = torch.as_tensor(np.asarray(maximum, dtype=np.float32))
        if lo.shape != self.centre.shape or hi.shape != self.centre.shape:
            raise ValueError(f"min/max shapes {tuple(lo.shape)}, {tuple(hi.shape)}; expected ({self.centre.numel()},)")
        if not (torch.isfinite(lo).all() and torch.isfinite(hi).all()) or bool((hi < lo).any()):
            raise ValueError("min/max must be finite with max >= min")
        self.centre.copy_((hi + lo) / 2)
        self.half_range.copy_(torch.clamp((hi - lo) / 2, min=MIN_HALF_RANGE))
        return self

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.centre) / self.half_range

    def unnormalize(self, y: torch.Tensor) -> torch.Tensor:
        return y * self.half_range + self.centre


def crop_offsets(n: int, height: int, width: int, size: int) -> torch.Tensor:
    """Random (top, left) offsets (n, 2) of square ``size`` crops in (height, width) images, from torch's global
    generator (all tops, then all lefts)."""
    tops = torch.randint(0, height - size + 1, (n,))
    lefts = torch.randint(0, width - size + 1, (n,))
    return torch.stack([tops, lefts], dim=-1)


def crop_images(images: torch.Tensor, size: int, random: bool, offsets: torch.Tensor | None = None) -> torch.Tensor:
    """Square crops (N, 3, size, size) of images (N, 3, H, W): a random one per image in training (``offsets``
    (N, 2) top/left, else drawn by `crop_offsets`), the centre one at inference."""
    n, _, height, width = images.shape
    if size <= 0 or (size == height and size == width):
        return images
    if not random:
        top, left = (height - size) // 2, (width - size) // 2
        return images[:, :, top:top + size, left:left + size]
    if offsets is None:
        offsets = crop_offsets(n, height, width, size)
    tops, lefts = offsets.to(images.device).unbind(-1)
    span = torch.arange(size, device=images.device)
    rows = (tops[:, None] + span)[:, None, :, None]  # (n, 1, size, 1)
    cols = (lefts[:, None] + span)[:, None, None, :]  # (n, 1, 1, size)
    batch = torch.arange(n, device=images.device)[:, None, None, None]
    channels = torch.arange(images.shape[1], device=images.device)[None, :, None, None]
    return images[batch, channels, rows, cols]  # one gather for all crops
