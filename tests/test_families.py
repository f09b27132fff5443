"""Procedural building families: registry, validity, free walks, determinism, files and the
simulator on every walk (symmetry: test_family_symmetry.py; faults: test_family_faults.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString

from mfcl_jax.floorplan.geojson import load_geojson
from mfcl_jax.report.plots_scene import plot_family
from mfcl_jax.sim.families import FAMILIES, make_scene, with_as_built, write_family_geojson
from mfcl_jax.sim.scenes import Scene
from mfcl_jax.sim.trajectory import sample_path
from tests._families import SEEDS, _driven, _min_dist, _same_region, all_scenes


@pytest.fixture(scope="module")
def scenes():
    return all_scenes()


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
