"""Procedural building families: validity, free walks, determinism, symmetry, faults, files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely import affinity
from shapely.geometry import LineString, MultiLineString

from mfcl_jax.floorplan.geojson import load_geojson
from mfcl_jax.report.plots_scene import plot_family
from mfcl_jax.sim.families import (
    FAMILIES,
    NotApplicable,
    make_scene,
    with_as_built,
    with_clutter,
    with_scale_error,
    write_family_geojson,
)
from mfcl_jax.sim.scenes import Scene
from mfcl_jax.sim.trajectory import sample_path

SEEDS = range(5)


@pytest.fixture(scope="module")
def scenes():
    return {(f, s): make_scene(f, s) for f in FAMILIES for s in SEEDS}


def _dense(wp, step=0.05):
    wp = np.asarray(wp, float)
    out = [wp[:1]]
    for a, b in zip(wp[:-1], wp[1:], strict=True):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + (b - a) * (np.arange(1, k + 1) / k)[:, None])
    return np.concatenate(out)


def _driven(wp):
    """Points along the waypoint polyline and along the smoothed path the simulator drives."""
    return np.concatenate([_dense(wp), sample_path(wp).poses[:, :2]])


def _min_dist(points, segments) -> float:
    lines = MultiLineString([s for s in np.asarray(segments)])
    return float(np.min(shapely.distance(lines, shapely.points(points))))


def _same_region(a, b, tol=1e-6) -> bool:
    return a.symmetric_difference(b).area < tol


# ---------------------------------------------------------------------------- registry
def test_registry_names_and_errors():
    assert FAMILIES == (
        "plain",
        "bays",
        "offices",
        "corridor",
        "hall",
        "ring",
        "rotational",
        "mirror",
    )
    with pytest.raises(ValueError, match=r"unknown family 'nope'.*plain, bays, offices"):
        make_scene("nope", 0)
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="seed"):
            make_scene("plain", bad)


# ---------------------------------------------------------------------------- validity
@pytest.mark.parametrize("family", FAMILIES)
def test_plans_valid(scenes, family):
    for s in SEEDS:
        sc = scenes[family, s]
        fp = sc.floorplan
        assert isinstance(sc, Scene) and sc.name == fp.name == f"{family}-{s}"
        assert sc.as_built is None
        names = fp.room_names
        assert len(set(names)) == len(names)
        x0, y0, x1, y1 = fp.bounds
        assert x1 - x0 <= 61.0 and y1 - y0 <= 46.0, fp.bounds
        assert (fp.thickness > 0).all() and len(fp.doors) == len(set(map(id, fp.doors)))
        for d in fp.doors:
            line = LineString(d.segment)
            for r in d.rooms:
                assert fp.room(r).polygon.distance(line) < 1e-6, (sc.name, d.rooms)
            # The opening is open: its centre is not inside a wall.
            assert not fp.wall_solid.contains(shapely.Point(d.segment.mean(0)))
        # Every room is reachable from every other through doors.
        reach = fp.adjacency.copy()
        for _ in range(len(names)):
            reach = reach | ((reach.astype(int) @ fp.adjacency.astype(int)) > 0)
        assert reach.all(), sc.name
        assert sc.clutter.ndim == 3 and len(sc.clutter) >= 4
        assert len(sc.trajectories) >= 3


@pytest.mark.parametrize("family", FAMILIES)
def test_rasterises_at_10cm(scenes, family):
    r = scenes[family, 0].floorplan.rasterize(0.10)
    assert r.shape[0] <= 480 and r.shape[1] <= 630
    assert (r.room_id >= 0).sum() > 0.5 * r.inside.sum()


@pytest.mark.parametrize("family", FAMILIES)
def test_walks_stay_in_free_space(scenes, family):
    for s in SEEDS:
        sc = scenes[family, s]
        fp = sc.floorplan
        footprint = fp.footprint
        for name, wp in sc.trajectories.items():
            smooth = sample_path(wp).s[-1]
            poly = float(np.sum(np.linalg.norm(np.diff(wp, axis=0), axis=1)))
            assert 30.0 <= smooth and poly <= 80.0, (sc.name, name, smooth, poly)
            pts = _driven(wp)
            assert _min_dist(pts, sc.segments) >= 0.35, (sc.name, name)
            assert shapely.contains_xy(footprint, pts[:, 0], pts[:, 1]).all()
            # Outside every room only inside a door opening, near its middle.
            loose = pts[np.array([r is None for r in fp.room_at(pts)])]
            for p in loose:
                ok = False
                for d in fp.doors:
                    c, n = d.segment.mean(0), np.diff(d.segment, axis=0)[0]
                    half = np.linalg.norm(n) / 2
                    n = n / (2 * half)
                    off = p - c
                    ok |= abs(off @ n) <= half and abs(off[0] * n[1] - off[1] * n[0]) <= 0.25
                assert ok, (sc.name, name, p)


@settings(max_examples=10, deadline=None)
@given(family=st.sampled_from(FAMILIES), seed=st.integers(0, 10**6))
def test_any_seed_builds_with_walks_in_free_space(family, seed):
    sc = make_scene(family, seed)
    assert len(sc.trajectories) >= 3
    for wp in sc.trajectories.values():
        assert _min_dist(_driven(wp), sc.segments) >= 0.35


def test_deterministic_and_seed_dependent():
    for family in FAMILIES:
        a, b = make_scene(family, 3), make_scene(family, 3)
        np.testing.assert_array_equal(a.floorplan.walls, b.floorplan.walls)
        np.testing.assert_array_equal(a.floorplan.thickness, b.floorplan.thickness)
        np.testing.assert_array_equal(a.clutter, b.clutter)
        assert a.trajectories.keys() == b.trajectories.keys()
        for k in a.trajectories:
            np.testing.assert_array_equal(a.trajectories[k], b.trajectories[k])
        for ra, rb in zip(a.floorplan.rooms, b.floorplan.rooms, strict=True):
            assert ra.name == rb.name and ra.polygon.equals_exact(rb.polygon, 0.0)
        walls = [make_scene(family, s).floorplan.wall_solid for s in (0, 1, 2)]
        assert not _same_region(walls[0], walls[1], 0.01)
        assert not _same_region(walls[1], walls[2], 0.01)


# ---------------------------------------------------------------------------- symmetry
def _centre(fp):
    x0, y0, x1, y1 = fp.bounds
    return ((x0 + x1) / 2, (y0 + y1) / 2)


def _rot_maps(fp, deg) -> bool:
    solid = fp.wall_solid
    return _same_region(affinity.rotate(solid, deg, origin=_centre(fp)), solid)


def _mirror_maps(fp) -> bool:
    solid = fp.wall_solid
    return _same_region(affinity.scale(solid, -1.0, 1.0, origin=_centre(fp)), solid)


def test_bays_are_exact_translated_copies(scenes):
    for s in SEEDS:
        fp = scenes["bays", s].floorplan
        bays = [r.polygon for r in fp.rooms if r.name.startswith("B")]
        assert 3 <= len(bays) <= 6
        c = np.array([[p.centroid.x, p.centroid.y] for p in bays])
        pitch = np.diff(c[:, 0])
        np.testing.assert_allclose(pitch, pitch[0], atol=1e-9)
        np.testing.assert_allclose(c[:, 1], c[0, 1], atol=1e-9)
        for p, ck in zip(bays, c, strict=True):
            moved = affinity.translate(p, *(c[0] - ck))
            iou = moved.intersection(bays[0]).area / moved.union(bays[0]).area
            assert iou > 1 - 1e-9
        # Doors at the same place in every bay.
        doors = [d for d in fp.doors if any(r.startswith("B") for r in d.rooms)]
        rel = [d.segment.mean(0) - c[k] for k, d in enumerate(doors)]
        np.testing.assert_allclose(np.asarray(rel) - rel[0], 0.0, atol=1e-9)


def test_rotational_symmetry_as_described():
    seen = set()
    for s in range(16):
        sc = make_scene("rotational", s)
        fp, desc = sc.floorplan, sc.description
        fold = 4 if "4-fold" in desc else 2
        exact = desc.endswith("exact")
        seen.add((fold, exact, "cross" if "cross" in desc else "loop"))
        assert _rot_maps(fp, 360 / fold) == exact, sc.name
        if exact:
            assert _rot_maps(fp, 180)
            assert _rot_maps(fp, 90) == (fold == 4), sc.name
            assert not _mirror_maps(fp), sc.name  # rotations only, no mirror
    assert {(f, e) for f, e, _ in seen} == {(2, True), (2, False), (4, True), (4, False)}
    assert {lay for *_, lay in seen} == {"cross", "loop"}


def test_mirror_maps_onto_itself_but_not_by_a_half_turn(scenes):
    for s in SEEDS:
        fp = scenes["mirror", s].floorplan
        assert _mirror_maps(fp) and not _rot_maps(fp, 180), fp.name
        for room in fp.rooms:
            if room.name.startswith("E"):
                twin = fp.room("W" + room.name[1:]).polygon
                assert _same_region(affinity.scale(room.polygon, -1.0, 1.0, origin=(0, 0)), twin)


def test_family_shapes(scenes):
    for s in SEEDS:
        fp = {f: scenes[f, s].floorplan for f in FAMILIES}
        assert 4 <= len(fp["plain"].rooms) <= 9
        offices = [r.polygon.area for r in fp["offices"].rooms if r.name.startswith("O")]
        assert 8 <= len(offices) <= 20 and max(offices) / min(offices) < 1.08
        ring = fp["ring"].room("K").polygon
        assert len(ring.interiors) == 1  # the ring corridor is one room with a hole
        x0, y0, x1, y1 = fp["corridor"].room("C").polygon.bounds
        assert 29.5 <= x1 - x0 <= 60.0 and 1.8 - 1e-9 <= y1 - y0 <= 3.0 + 1e-9
        hall = fp["hall"].room("H").polygon
        hx0, hy0, hx1, hy1 = hall.bounds
        assert len(hall.interiors) >= 4 and 19.5 <= min(hx1 - hx0, hy1 - hy0) <= 40


# ---------------------------------------------------------------------------- faults
def _same_scene_parts(a, b, plan=True, clutter=True, walks=True):
    if plan:
        assert a.floorplan is b.floorplan
    if clutter:
        np.testing.assert_array_equal(a.clutter, b.clutter)
    if walks:
        for k in a.trajectories:
            np.testing.assert_array_equal(a.trajectories[k], b.trajectories[k])


def _walks_clear(sc):
    for wp in sc.trajectories.values():
        assert _min_dist(_driven(wp), sc.segments) >= 0.35, sc.name


def test_scale_error_changes_the_plan_only():
    sc = make_scene("offices", 1)
    bad = with_scale_error(sc, 1.02)
    _same_scene_parts(sc, bad, plan=False)
    np.testing.assert_array_equal(bad.segments, sc.segments)  # the LiDAR's world is the same
    c = np.asarray(_centre(sc.floorplan))
    np.testing.assert_allclose(bad.floorplan.walls, c + 1.02 * (sc.floorplan.walls - c))
    np.testing.assert_allclose(bad.floorplan.room_areas, 1.02**2 * sc.floorplan.room_areas)
    assert bad.floorplan.room_names == sc.floorplan.room_names
    assert sc.as_built is None  # the input scene is untouched
    with pytest.raises(ValueError, match="factor"):
        with_scale_error(sc, 0.0)


@pytest.mark.parametrize("family,seed", [("plain", 0), ("bays", 2), ("ring", 1), ("corridor", 0)])
def test_missing_wall(family, seed):
    sc = make_scene(family, seed)
    dev = with_as_built(sc, "missing_wall", seed)
    _same_scene_parts(sc, dev)
    solid = sc.floorplan.wall_solid
    # Reality is the plan with something taken away: every real face lies on or in the
    # plan's walls, and some plan faces are gone.
    mids = shapely.points(dev.as_built.mean(axis=1))
    assert (shapely.distance(solid, mids) < 1e-6).all()
    plan_mids = sc.floorplan.wall_faces.mean(axis=1)
    gone = [_min_dist(m[None], dev.as_built) > 1e-3 for m in plan_mids]
    assert any(gone)
    _walks_clear(dev)


@pytest.mark.parametrize("family,seed", [("plain", 1), ("offices", 0), ("mirror", 2)])
def test_extra_partition(family, seed):
    sc = make_scene(family, seed)
    dev = with_as_built(sc, "extra_partition", seed)
    _same_scene_parts(sc, dev)
    inner = sc.floorplan.wall_solid.buffer(-1e-6)
    mids = dev.as_built.mean(axis=1)
    assert not shapely.contains_xy(inner, mids[:, 0], mids[:, 1]).any()  # nothing removed
    is_new = shapely.distance(sc.floorplan.wall_solid.boundary, shapely.points(mids)) > 1e-6
    assert is_new.sum() >= 2 and np.ptp(mids[is_new], axis=0).max() < 3.2  # one small partition
    for wp in sc.trajectories.values():
        assert _min_dist(_driven(wp), dev.as_built[is_new]) >= 0.5
    _walks_clear(dev)


@pytest.mark.parametrize("family,seed", [("bays", 0), ("offices", 2), ("rotational", 1)])
def test_moved_door(family, seed):
    sc = make_scene(family, seed)
    dev = with_as_built(sc, "moved_door", seed)
    _same_scene_parts(sc, dev, walks=False)
    # The faces round exactly one door of the plan moved; walks still clear reality.
    centres = shapely.points([d.segment.mean(0) for d in sc.floorplan.doors])
    plan = shapely.distance(MultiLineString(list(sc.floorplan.wall_faces)), centres)
    real = shapely.distance(MultiLineString(list(dev.as_built)), centres)
    assert (np.abs(real - plan) > 1e-6).sum() == 1
    _walks_clear(dev)
    with pytest.raises(ValueError, match="already has as-built"):
        with_as_built(dev, "moved_door", 0)


def test_as_built_errors():
    sc = make_scene("hall", 0)  # no doors, no interior walls
    with pytest.raises(ValueError, match="kind='nope'"):
        with_as_built(sc, "nope", 0)
    with pytest.raises(NotApplicable, match="no door"):  # the benchmark skips such runs
        with_as_built(sc, "moved_door", 0)


@pytest.mark.parametrize("fraction", [0.05, 0.3])
def test_with_clutter(fraction):
    sc = make_scene("plain", 2)
    more = with_clutter(sc, fraction, 7)
    _same_scene_parts(sc, more, clutter=False)
    assert more.as_built is None
    k = len(sc.clutter)
    np.testing.assert_array_equal(more.clutter[:k], sc.clutter)
    new = more.clutter[k:].reshape(-1, 4, 2, 2)  # axis-aligned rectangles, four sides each
    lo, hi = new.min(axis=(1, 2)), new.max(axis=(1, 2))
    area = np.prod(hi - lo, axis=1).sum() / sc.floorplan.room_areas.sum()
    got = float(more.description.split("clutter +")[1].split()[0])
    assert abs(got - area) < 1e-3 and got >= min(fraction, 0.2) - 0.01
    for wp in sc.trajectories.values():
        assert _min_dist(_driven(wp), more.clutter[k:]) >= 0.5 - 1e-9
    assert with_clutter(sc, fraction, 7).clutter.tobytes() == more.clutter.tobytes()
    with pytest.raises(ValueError, match="area_fraction"):
        with_clutter(sc, 0.7, 0)


# ---------------------------------------------------------------------------- files
@pytest.mark.parametrize("family", FAMILIES)
def test_geojson_round_trip(scenes, family, tmp_path):
    sc = scenes[family, 0]
    back = load_geojson(write_family_geojson(sc, tmp_path / f"{family}.geojson"))
    fp = sc.floorplan
    assert back.room_names == fp.room_names
    for a, b in zip(fp.rooms, back.rooms, strict=True):
        assert _same_region(a.polygon, b.polygon, 1e-9)
    assert [d.rooms for d in back.doors] == [d.rooms for d in fp.doors]
    np.testing.assert_allclose([d.segment for d in back.doors], [d.segment for d in fp.doors])
    np.testing.assert_allclose(back.walls, fp.walls)
    assert _same_region(back.wall_solid, fp.wall_solid, 1e-9)


def test_plot_family(tmp_path):
    sc = with_as_built(make_scene("bays", 1), "moved_door", 0)
    out = plot_family(sc, tmp_path / "sub" / "bays.png")
    assert out.exists() and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("family", FAMILIES)
def test_simulator_runs_every_walk(scenes, family):
    from mfcl_jax import windows as W
    from mfcl_jax.sim import LidarParams, SimParams, TrajectoryParams
    from mfcl_jax.sources.simulated import simulate

    # A smoke test that compiles once for all families: a sparse LiDAR and keyframes, the
    # first 30 m of every walk (31 keyframes each) and the segments padded to one capacity
    # bucket with far-away dummies beyond the LiDAR's range (walk geometry is checked above).
    traj = TrajectoryParams(scan_spacing=1.0)
    params = SimParams(lidar=LidarParams(n_beams=90), trajectory=traj)
    sc = scenes[family, 0]
    head = {k: _head(v, traj) for k, v in sc.trajectories.items()}
    far = np.zeros((1024 - len(sc.segments), 2, 2))
    far[:, :, 0] = 1e4 + np.arange(len(far))[:, None]
    far[:, 1, 1] = 0.5
    short = dataclasses.replace(
        sc,
        trajectories=head,
        clutter=np.concatenate([sc.clutter, far]),
        clutter_height=np.concatenate([sc.clutter_height, np.ones(len(far))]),
    )
    recs = simulate(short, seeds=(0,), params=params)
    assert [r.meta["trajectory"] for r in recs] == list(sc.trajectories)
    assert all(len(r.seq) == 31 for r in recs)
    assert all(len(W.cut(r.seq, W.WindowParams(d_s=6.0, keyframe_spacing=0.5))) > 0 for r in recs)


def _head(wp, params):
    """The shortest start of a polyline whose smoothed path is 30 m long."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(wp, axis=0), axis=1))])
    for length in np.arange(30.0, 36.0, 0.05):
        k = int(np.searchsorted(s, length))
        f = (length - s[k - 1]) / (s[k] - s[k - 1])
        head = np.concatenate([wp[:k], [wp[k - 1] + f * (wp[k] - wp[k - 1])]])
        if sample_path(head, params).s[-1] >= 30.0:
            return head
    raise AssertionError("walk too short")
