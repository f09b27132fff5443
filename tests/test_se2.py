"""SE(2) algebra: group axioms, wrapping, circular means, broadcasting, jit/vmap."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mfcl_jax import se2

coord = st.floats(-50, 50, allow_nan=False, width=32)
angle = st.floats(-10, 10, allow_nan=False, width=32)


def poses(n):
    return st.tuples(
        arrays(np.float32, (n,), elements=coord),
        arrays(np.float32, (n,), elements=coord),
        arrays(np.float32, (n,), elements=angle),
    ).map(lambda t: np.asarray(se2.make(*t)))


def close(a, b, tol=2e-3):
    a, b = np.asarray(a), np.asarray(b)
    dxy = np.abs(a[..., :2] - b[..., :2]).max()
    dth = np.abs(np.asarray(se2.angle_diff(a[..., 2], b[..., 2]))).max()
    return dxy < tol * (1 + np.abs(a[..., :2]).max()) and dth < tol


@given(poses(5), poses(5), poses(5))
def test_associativity(a, b, c):
    assert close(se2.compose(se2.compose(a, b), c), se2.compose(a, se2.compose(b, c)))


@given(poses(7))
def test_inverse_and_identity(a):
    e = se2.identity((7,))
    assert close(se2.compose(a, se2.inverse(a)), e)
    assert close(se2.compose(se2.inverse(a), a), e)
    assert close(se2.compose(a, e), a)
    assert close(se2.inverse(se2.inverse(a)), a)


@given(poses(4), poses(4))
def test_matrix_homomorphism(a, b):
    m = se2.to_matrix(a) @ se2.to_matrix(b)
    assert close(se2.from_matrix(m), se2.compose(a, b))


@given(poses(3), poses(3))
def test_anchor_order(y, x):
    """H = Y X^-1 maps the odometry frame to B: H X == Y."""
    h = se2.anchor(y, x)
    assert close(se2.compose(h, x), y)


def test_anchor_order_is_not_commutative():
    y = se2.make(3.0, 1.0, 0.7)
    x = se2.make(-2.0, 4.0, -1.1)
    assert not close(se2.anchor(y, x), se2.compose(se2.inverse(x), y))


@given(arrays(np.float32, (16,), elements=st.floats(-100, 100, width=32)))
def test_wrap_range_and_equivalence(t):
    w = np.asarray(se2.wrap(t))
    assert np.all(w > -np.pi - 1e-6) and np.all(w <= np.pi + 1e-6)
    assert np.allclose(np.cos(w), np.cos(t), atol=1e-4)
    assert np.allclose(np.sin(w), np.sin(t), atol=1e-4)


def test_wrap_at_pi():
    w = np.asarray(se2.wrap(jnp.asarray([np.pi, -np.pi, 3 * np.pi], jnp.float32)))
    # +-pi are one angle; float32 rounding decides which sign comes back.
    assert np.allclose(np.abs(w), np.pi, atol=1e-5)
    assert np.allclose(np.asarray(se2.angle_diff(w, np.float32(np.pi))), 0.0, atol=1e-5)


@given(st.floats(0.0, 0.5), st.integers(2, 9))
def test_circular_mean_straddling_pi(spread, n):
    t = np.linspace(np.pi - spread, np.pi + spread, n).astype(np.float32)
    m = float(se2.circular_mean(jnp.asarray(t)))
    assert abs(float(se2.angle_diff(m, np.pi))) < 1e-4


def test_circular_mean_weights_and_mask():
    t = jnp.asarray([0.1, 0.3, 2.0], jnp.float32)
    m = se2.circular_mean(t, jnp.asarray([1.0, 1.0, 0.0], jnp.float32))
    assert abs(float(m) - 0.2) < 1e-5


def test_mean_pose_masks_entries():
    p = se2.make(
        jnp.asarray([0.0, 2.0, 50.0]), jnp.asarray([1.0, 3.0, 50.0]), jnp.asarray([3.1, -3.1, 0.0])
    )
    m = np.asarray(se2.mean_pose(p, jnp.asarray([1.0, 1.0, 0.0], jnp.float32), axis=0))
    assert np.allclose(m[:2], [1.0, 2.0])
    assert abs(abs(m[2]) - np.pi) < 1e-3


@given(poses(6), poses(6))
def test_distance_pair_symmetric_and_separate(a, b):
    dxy, dth = se2.distance_pair(a, b)
    dxy2, dth2 = se2.distance_pair(b, a)
    assert np.allclose(dxy, dxy2, atol=1e-4) and np.allclose(dth, dth2, atol=1e-5)
    assert np.all(np.asarray(dth) <= np.pi + 1e-6)
    assert np.allclose(dxy, np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1]), atol=1e-3)


@given(poses(3))
def test_apply_matches_matrix(a):
    pts = np.asarray([[1.0, 2.0], [-3.0, 0.5]], np.float32)
    out = np.asarray(se2.apply(a[:, None, :].squeeze(1), np.broadcast_to(pts, (3, 2, 2))))
    hom = np.concatenate([pts, np.ones((2, 1), np.float32)], axis=1)
    ref = np.einsum("nij,pj->npi", np.asarray(se2.to_matrix(a)), hom)[..., :2]
    assert np.allclose(out, ref, atol=1e-3)


def test_broadcasting_over_leading_axes():
    a = se2.make(jnp.zeros((4, 1)), jnp.ones((4, 1)), jnp.zeros((4, 1)))
    b = se2.make(jnp.ones((1, 5)), jnp.zeros((1, 5)), jnp.full((1, 5), 0.5))
    assert se2.compose(a, b).shape == (4, 5, 3)
    assert se2.distance_pair(a, b)[0].shape == (4, 5)


@pytest.mark.parametrize("fn", [se2.compose, se2.anchor, se2.between])
def test_jit_vmap_agree(fn):
    rng = np.random.default_rng(0)
    a = jnp.asarray(rng.normal(size=(8, 3)), jnp.float32)
    b = jnp.asarray(rng.normal(size=(8, 3)), jnp.float32)
    eager = fn(a, b)
    assert np.allclose(jax.jit(fn)(a, b), eager, atol=1e-5)
    assert np.allclose(jax.vmap(fn)(a, b), eager, atol=1e-5)
