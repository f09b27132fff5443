"""``argmin`` and ``argmax`` as plain reductions, for XLA:CPU.

``jnp.argmin`` lowers to one reduction over (value, index) pairs, which XLA:CPU runs as a
scalar loop: in the LiDAR odometry's nearest-neighbour search (128 scan points against 1,280
map points, ten times per keyframe) it was four fifths of the kernel's time. Here the extreme
value is found first (a vectorised ``min``), then the first index that holds it (a second
``min``, over indices). The result is ``jnp.argmin``'s exactly: ties go to the first index,
and a NaN counts as the extreme (the first NaN wins), as in ``jnp.argmin``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["argmin", "argmax"]


def _first(hit, idx, n, axis):
    return jnp.min(jnp.where(hit, idx, n), axis=axis)


def argmin(x, axis: int = -1):
    """The first index of the smallest entry of ``x`` along ``axis`` (``int32``)."""
    axis = axis % x.ndim
    n = x.shape[axis]
    shape = [1] * x.ndim
    shape[axis] = n
    idx = jnp.arange(n, dtype=jnp.int32).reshape(shape)
    # one copy of ``x`` for both reductions: XLA may otherwise recompute an elementwise ``x``
    # inside each, and two computations of it need not agree to the last bit
    x = jax.lax.optimization_barrier(x)
    least = _first(x == jnp.min(x, axis=axis, keepdims=True), idx, n, axis)
    if not jnp.issubdtype(x.dtype, jnp.floating):
        return least
    # ``min`` propagates a NaN, which equals nothing: ``least`` is then ``n``
    return jnp.where(least < n, least, _first(jnp.isnan(x), idx, n, axis))


def argmax(x, axis: int = -1):
    """The first index of the largest entry of ``x`` along ``axis`` (``int32``)."""
    # order reversed exactly: negation for floats, bitwise not (``-x - 1``) for integers
    return argmin(-x if jnp.issubdtype(x.dtype, jnp.floating) else ~x, axis)
