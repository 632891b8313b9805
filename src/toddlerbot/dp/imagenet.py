"""Load ImageNet ResNet-18 weights a user has locally into the GroupNorm `ResNet18Encoder`.

The file is a torchvision-style state dict (``conv1.weight``, ``bn1.weight``, ``layer1.0.bn1.bias``,
``layer1.0.downsample.1.weight``, ``fc.weight``...) saved with ``torch.save``; it is read with
``weights_only=True`` (no pickled objects). Nothing is downloaded.

Mapping, decided per tensor: convolutions copy as they are. A BatchNorm's affine ``weight``/``bias`` (shape (C,))
become the GroupNorm's affine parameters (same shape, same role: per-channel scale and shift after normalising).
BatchNorm ``running_mean``/``running_var``/``num_batches_tracked`` have no GroupNorm counterpart (GroupNorm
normalises each sample by its own group statistics) and are dropped, so the pretrained features are approximate
until fine-tuned; fine-tuning is what the training run does anyway. ``fc`` (the 1000-class head) is dropped: the
encoder has its own projection.
"""

from __future__ import annotations

from pathlib import Path

import torch

from toddlerbot.dp.encoders import ResNet18Encoder
from toddlerbot.errors import ToddlerbotError
from toddlerbot.yaml_input import sized_file

DROPPED_SUFFIXES = ("running_mean", "running_var", "num_batches_tracked")


class PretrainedWeightsError(ToddlerbotError):
    """A local ImageNet weights file is missing, unreadable or does not fit ResNet-18."""


def torchvision_key(name: str) -> str:
    """Our parameter name -> the torchvision ResNet name it takes its value from."""
    parts = name.split(".")
    return ".".join("bn" + p[4:] if p.startswith("norm") else p for p in parts)


MAX_STATE_DICT_BYTES = 200_000_000
"""Largest ResNet-18 state dict read, bytes (torchvision's is 46.8 MB)."""


def load_imagenet_weights(encoder: ResNet18Encoder, path: str | Path) -> dict[str, list[str]]:
    """Copy a torchvision ResNet-18 state dict into ``encoder``'s trunk; returns ``{"loaded", "dropped"}`` names."""
    path = Path(path)
    if not path.exists():
        raise PretrainedWeightsError(f"{path}: no such file (ImageNet ResNet-18 state dict expected)")
    sized_file(path, "ResNet-18 state dict", PretrainedWeightsError, MAX_STATE_DICT_BYTES)
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types for corrupt or pickled-object files
        raise PretrainedWeightsError(f"{path}: not a weights-only torch state dict ({type(exc).__name__}: "
                                     f"{str(exc).splitlines()[0]})") from exc
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise PretrainedWeightsError(f"{path}: expected a dict of tensors (a ResNet-18 state dict)")
    own = encoder.state_dict()
    loaded: list[str] = []
    for name, target in own.items():
        if name.startswith("project."):
            continue
        source = torchvision_key(name)
        if source not in state:
            raise PretrainedWeightsError(f"{path}: missing {source} (needed for {name}); is it a ResNet-18?")
        if state[source].shape != target.shape:
            raise PretrainedWeightsError(f"{path}: {source} has shape {tuple(state[source].shape)}, "
                                         f"expected {tuple(target.shape)}")
        target.copy_(state[source].to(target.dtype))
        loaded.append(source)
    dropped = sorted(set(state) - set(loaded))
    unexpected = [k for k in dropped if not (k.endswith(DROPPED_SUFFIXES) or k.startswith("fc."))]
    if unexpected:
        raise PretrainedWeightsError(f"{path}: unexpected tensor {unexpected[0]} (not ResNet-18)")
    return {"loaded": loaded, "dropped": dropped}
