"""Procedural building families' faults: a scale error in the plan, as-built deviations (a
missing wall, an extra partition, a moved door) and extra clutter."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import MultiLineString

from mfcl_jax.sim.families import (
    NEAR_SYM_KINDS,
    NotApplicable,
    make_scene,
    with_as_built,
    with_clutter,
    with_near_symmetry,
    with_scale_error,
)
from mfcl_jax.sim.families.nearsym import MOVE, self_motion
from tests._families import _centre, _driven, _min_dist


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


@pytest.mark.parametrize("family, seed", [("rotational", 2), ("bays", 0)])
def test_near_symmetry_stub(family, seed):
    sc = make_scene(family, seed)
    g = self_motion(sc)
    assert g is not None
    built = {k: with_near_symmetry(sc, k, 0) for k in NEAR_SYM_KINDS}
    plan = built["stub_built"].floorplan
    stub = plan.walls[-1]
    assert len(plan.walls) == len(sc.floorplan.walls) + 1 and np.isclose(
        np.linalg.norm(stub[1] - stub[0]), 1.2
    )
    c, s_ = np.cos(g[2]), np.sin(g[2])
    image = stub @ np.array([[c, s_], [-s_, c]]) + g[:2]
    for k, s in built.items():
        # one plan, but for stub_twin's: the stub at the image of the walk's place
        want = image if k == "stub_twin" else stub
        np.testing.assert_allclose(s.floorplan.walls[-1], want, atol=1e-9, err_msg=k)
        np.testing.assert_array_equal(s.floorplan.walls[:-1], sc.floorplan.walls)
        _walks_clear(s)
    assert built["stub_built"].as_built is None
    np.testing.assert_array_equal(built["stub_unbuilt"].as_built, sc.floorplan.wall_faces)

    def near(faces, seg):  # distance from a stub's tip to the nearest real face
        return shapely.distance(MultiLineString(list(faces)), shapely.Point(seg[1]))

    assert near(built["stub_twin"].as_built, stub) < 0.1
    assert near(built["stub_twin"].as_built, image) < 0.1
    assert near(sc.floorplan.wall_faces, image) > 0.3  # the image stands in free space
    moved = built["stub_moved"].as_built
    assert near(moved, stub) > 0.25 and abs(near(moved, stub) - MOVE) < 0.1


def test_near_symmetry_needs_an_exact_self_motion():
    with pytest.raises(NotApplicable, match="no exact self-motion"):
        with_near_symmetry(make_scene("ring", 0), "stub_unbuilt", 0)
    with pytest.raises(ValueError, match="unknown kind"):
        with_near_symmetry(make_scene("rotational", 2), "stub", 0)
