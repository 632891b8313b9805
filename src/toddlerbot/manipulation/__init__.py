"""Manipulation from demonstrations: the diffusion policy (``dp``, PyTorch, extra ``[dp]``)."""
