"""Diffusion policy (appendix 8.12): image + joint-angle history at 10 Hz -> a 16-step action chunk.

Modules, one job each: ``config`` (plain-data configuration), ``normalize`` (min-max state/action scaling and the
one uint8 -> float image conversion), ``encoders`` (ResNet-18 with GroupNorm, small CNN), ``imagenet`` (local
ImageNet weights -> GroupNorm ResNet), ``unet`` (conditional 1-D U-Net with FiLM), ``scheduler`` (DDPM/DDIM),
``policy`` (the network + noise schedule), ``ema``, ``checkpoint``, ``data`` (window-dataset protocol, split by
episode, dataset adapter), ``train``, ``chunker`` and ``runner`` (10 Hz chunks -> 50 Hz targets, worker thread),
``evaluate`` (closed-loop success on a simulated task), ``live`` (a checkpoint as a runtime policy for
``sim run``/``hw run --policy dp``).
``chunker`` and ``runner`` need only numpy.
"""
