"""The numerical precision MJX training and evaluation need, set by the code itself.

On GPUs JAX's default float32 matrix multiply uses TensorFloat-32 (about 10 mantissa bits): the constraint
solver's matrices then lose enough precision that a robot which stands in the CPU simulator falls over within
two seconds (measured on an H100, see docs/rl.md). Full float32 precision must be selected before anything is
compiled, because the setting is read at trace time.
"""

from __future__ import annotations

MATMUL_PRECISION = "highest"


def use_full_precision() -> None:
    """Make JAX multiply matrices in full float32 (no TensorFloat-32) from now on."""
    import jax

    jax.config.update("jax_default_matmul_precision", MATMUL_PRECISION)
