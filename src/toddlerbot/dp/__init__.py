"""Diffusion policy (appendix 8.12): image + joint-angle history at 10 Hz -> a 16-step action chunk.

Modules, one job each: ``config`` (plain-data configuration), ``normalize`` (min-max state/action scaling and the
one uint8 -> float image conversion), ``encoders`` (ResNet-18 with GroupNorm, small CNN), ``imagenet`` (local
ImageNet weights -> GroupNorm ResNet), ``unet`` (conditional 1-D U-Net with FiLM), ``scheduler`` (DDPM/DDIM),
``policy`` (the network + noise schedule), ``ema``, ``checkpoint``, ``data`` (window-dataset protocol, split by
episode, dataset adapter), ``train`` (with ``distributed``: data-parallel under torchrun), ``chunker`` and
``runner`` (10 Hz chunks -> 50 Hz targets, worker thread), ``evaluate`` (closed-loop success on a simulated task),
``live`` (a checkpoint as a runtime policy for ``sim run``/``hw run --policy dp``).
``chunker`` and ``runner`` need only numpy.
"""

import importlib.util

from toddlerbot.errors import ToddlerbotError


def have_torch() -> bool:
    """Whether torch (the ``[dp]`` extra) is installed, without importing it."""
    return importlib.util.find_spec("torch") is not None


def require_torch(threads: int | None = None) -> None:
    """Import torch (the ``[dp]`` extra), setting its CPU threads when given; a one-line error where it is missing."""
    try:
        import torch
    except ImportError as exc:
        raise ToddlerbotError(f"the diffusion policy needs the [dp] extra (pip install 'toddlerbot[dp]'): {exc}") \
            from exc
    if threads is not None:
        torch.set_num_threads(threads)
