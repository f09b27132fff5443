"""Front-end stage kernels: eager vs jitted, the plan fields' sampling and gradient, the
refinement (score, pose, its gradient and preconditioner) and the block scores."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mfcl_jax import se2
from mfcl_jax.floorplan.raster import bilinear
from mfcl_jax.frontend import FrontendParams, features, hough, refine, verify
from tests._frontend import PARAMS, asym_run, feats_for


@pytest.fixture(scope="module")
def asym():
    return asym_run()


def test_jit_and_no_jit_agree(asym):
    """Each stage kernel, eager vs jitted, on a tiny submap (the whole eager pipeline costs
    ~30 s of per-op dispatch; the jitted pipeline is covered by the other tests)."""
    fp, subs, _, _ = asym
    tiny = FrontendParams(
        J=4,
        n_hough=8,
        n_prescreen=16,
        max_votes=64,
        hough_points=192,
        n_lines=8,
        n_corners=8,
        refine_steps=3,
        min_line_pts=8,
    )
    pts, org, Y = subs[0]
    pts, org, ok = pts[::8][:192], org[::8][:192], np.ones(192, bool)
    f = feats_for(fp)
    plan = (f.corner_pos, f.corner_a1, f.corner_a2, f.corner_kind, f.corner_valid)

    def stages(pts, org, ok):
        lines = features.detect_lines(pts, org, ok, tiny)
        corners = features.detect_corners(lines, ok, tiny)
        peaks, _, peak_ok, _, _ = hough.vote(*hough.corner_votes(corners, plan, tiny), tiny)
        y = jnp.concatenate([peaks[:3], jnp.asarray(Y, jnp.float32)[None] + 0.05], 0)
        q, q_ok = verify.free_samples(pts, org, ok, 2, 0.3)
        s = jax.vmap(lambda p: verify.score(p, pts, ok, q, q_ok, f, 0.07, 1.0))(y)
        return lines["u"], corners["pos"], peaks, peak_ok, s, refine.refine(y, pts, ok, f, tiny)

    eager, jitted = stages(pts, org, ok), jax.jit(stages)(pts, org, ok)
    for a, b in zip(eager, jitted, strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), atol=2e-3, rtol=1e-4)
    assert np.asarray(eager[3]).any()


def test_sample_matches_bilinear_and_its_gradient(asym):
    fp = asym[0]
    r = fp.rasterize(0.10)
    sdf, _ = verify.surface_fields(fp, r, 0.05)
    f4 = jnp.asarray(verify.stack4(sdf, verify.FAR))
    xy = np.random.default_rng(1).uniform([-1.5, -1.5], [17.5, 9.5], (200, 2)).astype(np.float32)
    v, g = verify.sample(r.origin, r.res, f4, xy, verify.FAR, grad=True)
    ref = bilinear(r.to_jax(), np.asarray(sdf), xy, verify.FAR)
    np.testing.assert_allclose(np.asarray(v), np.asarray(ref), rtol=1e-4, atol=1e-5)
    auto = jax.vmap(jax.grad(lambda p: verify.sample(r.origin, r.res, f4, p, verify.FAR)))(xy)
    np.testing.assert_allclose(np.asarray(g), np.asarray(auto), atol=1e-4)
    # Exact near walls: a point 3 cm off a wall face (x = 0.1) reads 3 cm, inside reads < 0.
    np.testing.assert_allclose(
        verify.sample(r.origin, r.res, f4, np.float32([[0.13, 4.0], [0.05, 4.0]]), 10.0),
        [0.03, -0.05],
        atol=1e-3,
    )


def test_refinement_improves_the_score_and_the_pose(asym):
    fp, subs, _, _ = asym
    pts, _, Y = subs[0]
    f = feats_for(fp)
    ok = np.ones(len(pts), bool)
    off = np.array([[0.07, -0.05, math.radians(0.8)], [-0.12, 0.03, math.radians(-1.5)]])
    y0 = (Y + off).astype(np.float32)
    y1 = jax.jit(lambda y: refine.refine(y, pts, ok, f, PARAMS))(y0)
    s = jax.vmap(lambda y: verify.occupancy(y, pts, ok, f, PARAMS.sigma_occ))
    assert np.all(np.asarray(s(y1)) > np.asarray(s(y0)))
    dxy, dth = se2.distance_pair(y1, Y.astype(np.float32))
    assert np.all(np.asarray(dxy) < 0.01), dxy
    assert np.all(np.asarray(dth) < math.radians(0.1)), dth


def test_refinement_gradient_is_the_score_gradient(asym):
    """The optax chain is fed the exact gradient of the smooth score (in lever-scaled units),
    and its Gauss-Newton preconditioner solves the damped normal equations."""
    fp, subs, _, _ = asym
    pts, _, Y = subs[0]
    f = feats_for(fp)
    ok = np.ones(len(pts), bool)
    pose0 = (Y + np.array([0.04, -0.03, math.radians(0.5)])).astype(np.float32)
    lever, sigma = np.float32(PARAMS.yaw_lever), np.float32(0.15)

    def neg_score(v):
        pose = pose0 + v * jnp.stack([jnp.float32(1), jnp.float32(1), 1 / lever])
        return -verify.occupancy(pose, pts, ok, f, sigma)

    @jax.jit  # one compilation instead of ~5 s of eager dispatch
    def check(u):
        g, nrm = refine.grad_and_normal(u, pose0, lever, pts, ok.astype(np.float32), f, sigma)
        step, _ = refine.scale_by_gauss_newton(0.0).update(g, None, normal=nrm)
        return g, nrm, step, jax.grad(neg_score)(u)

    g, nrm, step, auto = (np.asarray(a) for a in check(np.float32([0.01, 0.02, -0.01])))
    np.testing.assert_allclose(g, auto, rtol=1e-3, atol=1e-5)
    np.testing.assert_allclose(nrm, nrm.T, rtol=1e-5)
    assert np.all(np.linalg.eigvalsh(nrm) >= -1e-6)
    np.testing.assert_allclose(nrm @ step, g, rtol=1e-3, atol=1e-5)
    with pytest.raises(ValueError, match="damping"):
        refine.scale_by_gauss_newton(-1.0)
    with pytest.raises(ValueError, match="yaw_lever"):
        FrontendParams(yaw_lever=0.0)
    with pytest.raises(ValueError, match="refine_lr"):
        FrontendParams(refine_lr=0.01)


def test_block_scores_are_the_score_of_contiguous_blocks_of_the_points():
    """``verify.block_scores``: block b holds the b-th quarter of the valid points (in order)
    with their own free samples; each block's number is ``score_fields`` of those points."""
    rng = np.random.default_rng(3)
    n, m, nb = 20, 3, 4
    hit = jnp.asarray(rng.uniform(0, 1, n), jnp.float32)
    pen = jnp.asarray(rng.uniform(0, 1, n * m), jnp.float32)
    ok = np.ones(n, bool)
    ok[[2, 17]] = False  # 18 valid points: blocks of 4, 5, 4, 5 by rank
    q_ok = np.repeat(ok, m)
    q_ok[5] = False  # one free sample of point 1 is not free
    got = np.asarray(verify.block_scores(hit, pen, jnp.asarray(ok), jnp.asarray(q_ok), nb, 0.5))
    rank = np.cumsum(ok) - 1
    block = np.where(ok, rank * nb // ok.sum(), -1)
    for b in range(nb):
        sel = block == b
        qs = np.repeat(sel, m) & q_ok
        want = float(np.asarray(hit)[sel].mean() - 0.5 * np.asarray(pen)[qs].mean())
        np.testing.assert_allclose(got[b], want, rtol=1e-5)
    assert [int((block == b).sum()) for b in range(nb)] == [5, 4, 5, 4]
    # a difference confined to one block shows in that block alone
    local = hit.at[15].add(-0.9)
    d = got - np.asarray(
        verify.block_scores(local, pen, jnp.asarray(ok), jnp.asarray(q_ok), nb, 0.5)
    )
    assert d[int(block[15])] > 0.15 and np.allclose(np.delete(d, int(block[15])), 0.0)
