"""Front-end tests: registration, equivariance, symmetry, jit, traces, refinement, sampling,
common shape buckets, bad inputs, CSV."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _frontend_synth import batch, make_submap
from shapely.geometry import box

from mfcl_jax import se2
from mfcl_jax.floorplan.model import Door, Floorplan, Room
from mfcl_jax.floorplan.raster import Rasters, bilinear, pad_to
from mfcl_jax.frontend import (
    FrontendParams,
    build_features,
    common_features,
    features,
    hough,
    load_candidates_csv,
    make_register,
    refine,
    registration,
    sanitize_submaps,
    verify,
)
from mfcl_jax.frontend.features import floorplan_corners
from mfcl_jax.sim.scenes import get_scene
from mfcl_jax.windows.arrays import SubmapBatch

N, P = 4, 2048
SHAPE = (200, 360)  # common raster bucket: one compilation for every test floor plan
PARAMS = FrontendParams()
REG = make_register(PARAMS)


def asym_plan() -> Floorplan:
    """Two rooms of different size, one L-shaped, joined by a door (no symmetry)."""
    walls = [
        [[0, 0], [16, 0]],
        [[16, 0], [16, 8]],
        [[16, 8], [0, 8]],
        [[0, 8], [0, 0]],
        [[9, 0], [9, 5]],
        [[9, 6.5], [9, 8]],
        [[0, 5.5], [3, 5.5]],
        [[3, 5.5], [3, 8]],
    ]
    rooms = (
        Room("A", box(0.1, 0.1, 8.9, 7.9).difference(box(0, 5.4, 3.1, 8))),
        Room("B", box(9.1, 0.1, 15.9, 7.9)),
    )
    return Floorplan(
        walls=np.asarray(walls, float),
        thickness=0.2,
        rooms=rooms,
        doors=(Door(np.array([[8.7, 5.75], [9.3, 5.75]]), ("A", "B")),),
        name="asym",
    )


def feats_for(fp):
    r = pad_to(fp.rasterize(0.10), SHAPE, n_rooms=8)
    return build_features(fp, PARAMS, rasters=r, corners=floorplan_corners(fp, capacity=64))


def pad_batch(subs):
    """Batch of N slots (missing ones empty), capacity P."""
    b = batch(subs, P)
    n = len(subs)

    def pad(a, fill=0):
        return np.concatenate(
            [np.asarray(a), np.full((N - n, *np.shape(a)[1:]), fill, np.asarray(a).dtype)]
        )

    return SubmapBatch(
        points=pad(b.points),
        origins=pad(b.origins),
        mask=pad(b.mask, False),
        X=pad(b.X),
        run=pad(b.run),
        window=pad(b.window),
        t=pad(b.t),
        n_dropped=pad(b.n_dropped),
    )


def hits(cands, i, Y, xy=0.5, deg=2.0):
    dxy, dth = se2.distance_pair(cands.pose[i], np.asarray(Y, np.float32))
    return np.asarray((dxy < xy) & (dth < math.radians(deg)) & cands.mask[i])


@pytest.fixture(scope="module")
def asym():
    fp = asym_plan()
    subs = [
        make_submap(fp, (2.0, 2.0), (6.0, 3.0), 0.4, n_beams=240),
        make_submap(fp, (11.0, 2.0), (14.0, 5.0), -2.0, n_beams=240),
        make_submap(fp, (6.0, 6.5), (2.0, 4.0), 2.5, n_beams=240),
    ]
    before = registration.TRACE_COUNT[0]
    c = REG(pad_batch(subs), feats_for(fp))
    return fp, subs, c, registration.TRACE_COUNT[0] - before


def test_noise_free_submap_true_pose_top1(asym):
    fp, subs, c, _ = asym
    for i, (_, _, Y) in enumerate(subs):
        h = hits(c, i, Y, 0.1, 1.0)
        assert h[0], f"submap {i}: top-1 {np.asarray(c.pose[i, 0])} vs truth {Y}"
    assert int(c.reason[3]) == 1  # the padded empty slot


def test_equivariance_under_moving_the_plan(asym):
    fp, subs, c, _ = asym
    g = np.array([3.0, -2.0, 0.7])
    c2 = REG(pad_batch(subs), feats_for(fp.transformed(g)))
    for i in range(len(subs)):
        moved = np.asarray(se2.compose(g, c.pose[i]))
        for j in np.flatnonzero(np.asarray(c.mask[i]))[:5]:
            dxy, dth = se2.distance_pair(c2.pose[i], moved[j])
            ok = np.asarray((dxy < 0.2) & (dth < math.radians(1.5)) & c2.mask[i])
            assert ok.any(), f"submap {i} candidate {j} has no image under g"
        assert hits(c2, i, se2.compose(g, subs[i][2]), 0.15, 1.0)[0]


def test_symmetric_bays_yield_alias_candidates():
    scene = get_scene("symmetric_bays")
    fp = scene.floorplan
    pitch = 7.30
    sub = make_submap(fp, (8.8, 3.0), (12.8, 4.4), 0.3, n_beams=240)
    c = REG(pad_batch([sub]), feats_for(fp))
    Y = sub[2]
    assert hits(c, 0, Y).any()
    for k in (-1, 1, 2):
        alias = Y + np.array([k * pitch, 0.0, 0.0])
        assert hits(c, 0, alias).any(), f"no candidate in the bay shifted by {k} pitch"


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
    sdf, _ = verify.plan_fields(fp, r, 0.05)
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


def corridor_plan() -> Floorplan:
    """A 30 m x 2 m corridor with one room off its west end (no symmetry)."""
    walls = [
        [[0, 0], [30, 0]],
        [[30, 0], [30, 2]],
        [[30, 2], [8, 2]],
        [[8, 2], [8, 8]],
        [[8, 8], [0, 8]],
        [[0, 8], [0, 0]],
    ]
    rooms = (Room("C", box(0.1, 0.1, 29.9, 1.9).union(box(0.1, 1.9, 7.9, 7.9))),)
    return Floorplan(walls=np.asarray(walls, float), thickness=0.2, rooms=rooms, name="corr")


def test_dense_hypotheses_place_a_submap_without_corners():
    """Mid-corridor, 4 m of range: two parallel walls, no corner, so the corner Hough has no
    peak (reason 3 without the dense hypotheses). The dense peaks recover the heading and the
    offset across the corridor, which is all the scan determines."""
    fp = corridor_plan()
    sub = make_submap(fp, (14.0, 0.6), (16.5, 0.6), 0.0, n_beams=240, max_range=4.0)
    b = pad_batch([sub])
    off = FrontendParams(dense_n=0)
    r = pad_to(fp.rasterize(0.10), SHAPE, n_rooms=8)
    c_off = make_register(off)(b, build_features(fp, off, rasters=r))
    assert int(c_off.reason[0]) == 3 and not np.asarray(c_off.mask[0]).any()
    c = REG(b, feats_for(fp))
    assert int(c.reason[0]) == 0
    m = np.asarray(c.mask[0])
    pose = np.asarray(c.pose[0])[m]
    dth = np.abs(np.angle(np.exp(1j * pose[:, 2])))
    good = (np.abs(pose[:, 1] - 0.6) < 0.1) & (dth < math.radians(1.0))
    assert good.any(), pose[:5]
    # the best candidate is somewhere along the corridor (or turned round in it)
    assert 0.0 < pose[0, 1] < 2.0 and pose[0, 0] > 8.0


def test_plan_wall_directions():
    from mfcl_jax.frontend.dense import plan_directions

    pos, a1, a2, kind, valid = floorplan_corners(asym_plan(), capacity=64)
    dirs, ok = plan_directions(a1, a2, valid, 3)
    d = np.degrees(dirs[ok])
    assert len(d) >= 2
    assert sorted(np.round(d[:2], 3).tolist()) == [0.0, 90.0]
    dirs, ok = plan_directions(a1, a2, np.zeros_like(np.asarray(valid)), 3)
    assert not ok.any()


def test_common_features_one_trace_for_both_buildings():
    fps = [get_scene(n).floorplan for n in ("three_rooms", "symmetric_bays")]
    fa, fb = common_features(fps, PARAMS)
    shapes = lambda f: [np.shape(a) for a in jax.tree.leaves(f)]  # noqa: E731
    assert shapes(fa) == shapes(fb)
    sub = make_submap(fps[1], (8.8, 3.0), (12.8, 4.4), 0.3, n_beams=240)
    b = pad_batch([sub])
    before = registration.TRACE_COUNT[0]
    ca, cb = REG(b, fa), REG(b, fb)
    assert registration.TRACE_COUNT[0] - before == 1
    assert ca.pose.shape == cb.pose.shape == (N, PARAMS.J, 3)
    # Padding keeps the plan in place: the truth scores best. The bays are symmetric, so the
    # one-pitch alias ties with the truth to the last bit and rounding orders the two.
    best = np.asarray(cb.score[0]) >= float(cb.score[0, 0]) - 1e-6
    assert (hits(cb, 0, sub[2], 0.1, 1.0) & best).any()


def test_one_trace_for_every_batch_of_a_shape(asym):
    fp, subs, _, traced = asym
    assert traced == 1  # the fixture's first call: one trace for the whole batch
    before = registration.TRACE_COUNT[0]
    REG(pad_batch(subs[:1]), feats_for(fp.transformed((1.0, 0.0, 0.0))))
    REG(pad_batch(subs[1:]), feats_for(fp))
    assert registration.TRACE_COUNT[0] == before


def test_bad_inputs_give_reasons(asym):
    fp, subs, _, _ = asym
    pts, org, Y = subs[0]
    few = (pts[:10], org[:10], Y)
    nan = (np.full_like(pts, np.nan), org, Y)
    b = pad_batch([few, nan, subs[1]])
    clean = sanitize_submaps(b)
    assert int(clean.n_dropped[1]) == min(len(pts), P) and not clean.mask[1].any()
    c = REG(b, feats_for(fp))  # NaNs reach the kernel unsanitised: still no crash
    assert [int(r) for r in c.reason] == [2, 1, 0, 1]
    assert not np.asarray(c.mask)[[0, 1, 3]].any()
    assert np.isfinite(np.asarray(c.pose)).all()
    # A floor plan without walls: empty wall raster, no corners.
    f = feats_for(fp)
    r = f.rasters
    nowall = Rasters(
        origin=r.origin,
        dist=np.full(SHAPE, 50.0, np.float32),
        wall=np.zeros(SHAPE, bool),
        room_id=r.room_id,
        inside=r.inside,
        adjacency=r.adjacency,
        room_centroids=r.room_centroids,
        res=r.res,
    )
    empty = tuple(np.zeros_like(np.asarray(a)) for a in floorplan_corners(fp, capacity=64))
    c = REG(b, build_features(None, PARAMS, rasters=nowall, corners=empty))
    assert [int(x) for x in c.reason] == [2, 1, 4, 1]
    assert not np.asarray(c.mask).any()


def test_csv_adapter(tmp_path):
    p = tmp_path / "c.csv"
    p.write_text("submap,x,y,yaw_deg,score\n0,1,2,90,0.5\n0,3,4,-90,0.9\n2,0,0,0,0.1\n")
    c = load_candidates_csv(p, n_submaps=3, J=4)
    assert c.pose.shape == (3, 4, 3) and c.mask.sum() == 3
    np.testing.assert_allclose(c.pose[0, 0], [3, 4, -math.pi / 2], atol=1e-6)
    assert list(c.reason) == [0, 3, 0]
    bad = {
        "submap,x,y,score\n0,1,2,3\n": "missing column",
        "submap,x,y,yaw_deg,score\n0,1,2,90,0.5\n0,1,abc,90,0.5\n": "line 3: field 'y'",
        "submap,x,y,yaw_deg,score\n7,1,2,90,0.5\n": "line 2: field 'submap'",
        "submap,x,y,yaw_deg,score\n0,1,2,nan,0.5\n": "field 'yaw_deg'",
    }
    for text, msg in bad.items():
        p.write_text(text)
        with pytest.raises(ValueError, match=msg) as e:
            load_candidates_csv(p, n_submaps=3, J=4)
        assert str(p) in str(e.value)


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
