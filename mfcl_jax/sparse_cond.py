"""``sparse_cond``: a branch that stays a branch under ``vmap``.

``lax.cond`` with a batched predicate becomes a ``select``: both branches run for every row.
That is right for cheap branches and ruinous for an expensive one that few rows take (the
certification of a commit, a global search for rivals, the LiDAR odometry's jump test: each
needed in a few percent of the windows or keyframes). ``sparse_cond(pred, f, x)`` returns
``f(x)`` where ``pred`` holds and zeros elsewhere; unbatched it is a ``lax.cond``, and under
``vmap`` its batching rule visits only the rows whose predicate holds (a ``while_loop`` over
them, each row computed unbatched), so the cost follows the number of rows that need the
branch. Nested ``vmap``s apply the rule at every level.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax import custom_batching

__all__ = ["sparse_cond"]


# ``f`` wrapped once in ``jax.jit``: the branch, its zeros' shape (``eval_shape``) and the
# batching rule's rows then share one trace of ``f`` per input shape (a nested ``jit`` is
# inlined when the program compiles, so only tracing time changes); bounded, so that a
# caller passing a fresh closure per trace holds no more than the last few
_jitted = functools.lru_cache(maxsize=64)(jax.jit)


def _zeros(f, x):
    return jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), jax.eval_shape(f, x))


def _next(pred, start):
    """Index of the first row ``>= start`` whose predicate holds (the row count if none)."""
    idx = jnp.arange(pred.shape[0])
    return jnp.min(jnp.where(pred & (idx >= start), idx, pred.shape[0]))


def sparse_cond(pred, f, x, dense: bool = False):
    """``f(x)`` if ``pred`` else zeros of its shape; under ``vmap`` only true rows compute.

    Args:
        pred: ``()`` bool.
        f: a pure function of the pytree ``x``. It must not close over traced values (pass
            them in ``x``): a batching rule cannot see inside a closure.
        x: operands.
        dense: under ``vmap``, where every row's predicate holds, compute ``f`` batched
            instead of row by row (a second copy of ``f`` in the batched program; for a branch
            that every row takes at some calls and few at others).

    Returns:
        ``f(x)``, or a pytree of zeros shaped like it.
    """
    f = _jitted(f)

    @custom_batching.custom_vmap
    def branch(pred, x):
        return jax.lax.cond(pred, f, lambda v: _zeros(f, v), x)

    @branch.def_vmap
    def rule(axis_size, in_batched, pred, x):
        pb, xb = in_batched
        if not pb:
            pred = jnp.broadcast_to(pred, (axis_size,))

        def row(i):
            return jax.tree.map(lambda a, b: a[i] if b else a, x, xb)

        out = jax.tree.map(lambda s: jnp.zeros((axis_size, *s.shape), s.dtype),
                           jax.eval_shape(f, row(0)))  # fmt: skip

        def body(carry):
            i, out = carry
            # recursion: an outer vmap sees ``sparse_cond`` again and applies this rule
            y = sparse_cond(pred[i], f, row(i))
            out = jax.tree.map(lambda o, v: o.at[i].set(v), out, y)
            return _next(pred, i + 1), out

        def sparse(_):
            return jax.lax.while_loop(lambda c: c[0] < axis_size, body, (_next(pred, 0), out))[1]

        if dense:
            axes = jax.tree.map(lambda b: 0 if b else None, xb)
            out = jax.lax.cond(jnp.all(pred), lambda _: jax.vmap(f, in_axes=(axes,))(x), sparse,
                               None)  # fmt: skip
        else:
            out = sparse(None)
        return out, jax.tree.map(lambda _: True, out)

    return branch(pred, x)
