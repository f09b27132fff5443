"""Front-end registration: the true pose on top, equivariance, symmetry aliases, dense
hypotheses without corners, common shape buckets (one trace), bad inputs, the CSV adapter."""

from __future__ import annotations

import math

import jax
import numpy as np
import pytest
from _frontend_synth import make_submap
from shapely.geometry import box

from mfcl_jax import se2
from mfcl_jax.floorplan.model import Floorplan, Room
from mfcl_jax.floorplan.raster import Rasters, pad_to
from mfcl_jax.frontend import (
    FrontendParams,
    build_features,
    common_features,
    load_candidates_csv,
    make_register,
    registration,
    sanitize_submaps,
)
from mfcl_jax.frontend.features import floorplan_corners
from mfcl_jax.sim.scenes import get_scene
from tests._frontend import (
    PARAMS,
    REG,
    SHAPE,
    N,
    P,
    asym_plan,
    asym_run,
    feats_for,
    hits,
    pad_batch,
)


@pytest.fixture(scope="module")
def asym():
    return asym_run()


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
