"""``sparse_cond``: ``f(x)`` where the predicate holds and zeros elsewhere, unbatched, under
``vmap`` row by row, and (``dense``) batched where every row holds."""

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.sparse_cond import sparse_cond


def _f(ops):
    a, b = ops
    return {"s": jnp.sum(a * b), "v": a * 2.0 + b}


def test_each_row_gets_f_where_its_predicate_holds_and_zeros_elsewhere():
    rng = np.random.default_rng(0)
    a = jnp.asarray(rng.normal(size=(5, 3)), jnp.float32)
    b = jnp.float32(1.5)  # unbatched operand beside a batched one
    want = jax.vmap(lambda r: _f((r, b)))(a)
    for dense in (False, True):
        g = jax.jit(jax.vmap(lambda p, r, d=dense: sparse_cond(p, _f, (r, b), dense=d)))
        for pred in ([True] * 5, [True, False, False, True, False], [False] * 5):
            p = np.asarray(pred)
            got = g(jnp.asarray(p), a)
            np.testing.assert_allclose(got["s"], np.where(p, want["s"], 0.0), rtol=1e-6)
            np.testing.assert_allclose(got["v"], np.where(p[:, None], want["v"], 0.0), rtol=1e-6)
    one = sparse_cond(jnp.bool_(True), _f, (a[0], b), dense=True)
    np.testing.assert_allclose(one["s"], want["s"][0], rtol=1e-6)
    assert float(sparse_cond(jnp.bool_(False), _f, (a[0], b))["s"]) == 0.0
