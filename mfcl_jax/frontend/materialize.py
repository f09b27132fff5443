"""Compute-once values for XLA:CPU: ``materialize`` keeps a cheap-to-store array from being
recomputed inside every loop that reads it.

XLA fuses an elementwise producer into its consumers. When a consumer broadcasts it (one
submap's points read once per candidate pose, a pose's heading read once per point), the
producer's work is repeated per consumer element: a free-space sample's square root and
division once per (pose, sample) instead of once per sample, a heading's sine and cosine once
per point instead of once per pose. On XLA:CPU that made a field lookup ~4x dearer, and
``jax.lax.optimization_barrier`` does not help there (the CPU pipeline drops it before
fusion). The operands of a sort, however, are always materialised: sorting by an already
ordered key returns every value in place, at the cost of one pass over sorted data.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["materialize"]


def materialize(*arrays):
    """Returns ``arrays`` unchanged, each computed once into memory (see module docstring).

    Args:
        arrays: arrays of one size (any shapes and dtypes).

    Returns:
        A tuple of the same arrays.
    """
    size = arrays[0].size
    if any(a.size != size for a in arrays):
        raise ValueError(f"materialize: arrays of one size needed, got {[a.shape for a in arrays]}")
    flat = [a.reshape(-1) for a in arrays]
    out = jax.lax.sort((jnp.arange(size, dtype=jnp.int32), *flat), num_keys=1)[1:]
    return tuple(o.reshape(a.shape) for o, a in zip(out, arrays, strict=True))
