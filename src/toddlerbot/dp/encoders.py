"""Image encoders written with torch alone: ResNet-18 with GroupNorm (appendix) and a small CNN for CPU training.

Both take float images in [0, 1] (`normalize.images_to_unit`), shape (B, 3, H, W), and return (B, feature_dim).
GroupNorm instead of BatchNorm: statistics per sample, so training batches and single-frame inference agree and the
EMA copy needs no running statistics.
"""

from __future__ import annotations

import torch
from torch import nn

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def group_norm(channels: int) -> nn.GroupNorm:
    """GroupNorm with 16 channels per group (at least one group), as diffusion-policy ResNets use."""
    return nn.GroupNorm(max(1, channels // 16), channels)


class BasicBlock(nn.Module):
    """ResNet basic block; parameter names follow torchvision's with ``norm`` for ``bn`` (see `imagenet`)."""

    def __init__(self, in_channels: int, channels: int, stride: int) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, channels, 3, stride, 1, bias=False)
        self.norm1 = group_norm(channels)
        self.conv2 = nn.Conv2d(channels, channels, 3, 1, 1, bias=False)
        self.norm2 = group_norm(channels)
        self.downsample = None
        if stride != 1 or in_channels != channels:
            self.downsample = nn.Sequential(nn.Conv2d(in_channels, channels, 1, stride, bias=False),
                                            group_norm(channels))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = torch.relu(self.norm1(self.conv1(x)))
        out = self.norm2(self.conv2(out))
        return torch.relu(out + (x if self.downsample is None else self.downsample(x)))


class ResNet18Encoder(nn.Module):
    """ResNet-18 (GroupNorm) -> global average pool -> linear projection to ``feature_dim``."""

    def __init__(self, feature_dim: int = 512) -> None:
        super().__init__()
        self.register_buffer("mean", torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(IMAGENET_STD).view(1, 3, 1, 1), persistent=False)
        self.conv1 = nn.Conv2d(3, 64, 7, 2, 3, bias=False)
        self.norm1 = group_norm(64)
        self.maxpool = nn.MaxPool2d(3, 2, 1)
        widths = (64, 128, 256, 512)
        in_channels = 64
        for i, width in enumerate(widths):
            stride = 1 if i == 0 else 2
            setattr(self, f"layer{i + 1}", nn.Sequential(BasicBlock(in_channels, width, stride),
                                                         BasicBlock(width, width, 1)))
            in_channels = width
        self.project = nn.Linear(512, feature_dim)

    def trunk(self, images: torch.Tensor) -> torch.Tensor:
        """(B, 512) pooled features of images in [0, 1] (ImageNet mean/std applied here)."""
        x = (images - self.mean) / self.std
        x = self.maxpool(torch.relu(self.norm1(self.conv1(x))))
        for i in range(1, 5):
            x = getattr(self, f"layer{i}")(x)
        return x.mean(dim=(2, 3))

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.project(self.trunk(images))


class SmallCNNEncoder(nn.Module):
    """Stride-2 3x3 convolutions with GroupNorm and ReLU -> global average pool -> linear (CPU-sized)."""

    def __init__(self, channels: tuple[int, ...] = (16, 32, 64, 64), feature_dim: int = 64) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        in_channels = 3
        for width in channels:
            layers += [nn.Conv2d(in_channels, width, 3, 2, 1), nn.GroupNorm(min(8, width), width), nn.ReLU()]
            in_channels = width
        self.body = nn.Sequential(*layers)
        self.project = nn.Linear(in_channels, feature_dim)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.project(self.body(images * 2 - 1).mean(dim=(2, 3)))
