"""Built-in scenes: names, (non-)congruence, doors, trajectories inside and in order."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import LineString, Point

from mfcl_jax.sim.scenes import BAY_PITCH, SCENES, get_scene, symmetric_bays, three_rooms
from mfcl_jax.sim.trajectory import sample_path


@pytest.fixture(scope="module")
def tr():
    return three_rooms()


@pytest.fixture(scope="module")
def sb():
    return symmetric_bays()


def _corners(poly):
    return len(poly.exterior.coords) - 1


def _room_sequence(scene, name):
    """Rooms visited along a trajectory, consecutive duplicates and doorways removed."""
    poses = sample_path(scene.trajectories[name]).poses
    seq = []
    for r in scene.floorplan.room_at(poses[:, :2]):
        if r is not None and (not seq or seq[-1] != r):
            seq.append(r)
    return seq


def test_registry_and_unknown_name():
    assert set(SCENES) == {"three_rooms", "symmetric_bays"}
    for name in SCENES:
        assert get_scene(name).name == name
    with pytest.raises(KeyError, match="unknown scene 'nope'.*symmetric_bays"):
        get_scene("nope")


def test_room_names(tr, sb):
    assert tr.floorplan.room_names == ("207", "208", "209")
    assert sb.floorplan.room_names == ("R1", "R2", "R3", "R4")


def test_three_rooms_similar_but_not_congruent(tr):
    fp = tr.floorplan
    areas = fp.room_areas
    assert len(set(np.round(areas, 3))) == 3
    corners = [_corners(r.polygon) for r in fp.rooms]
    assert len(set(corners)) == 3, corners
    # Similar: same depth, lengths within 1 m of each other, shorter side 10-14 m.
    bounds = np.array([r.polygon.bounds for r in fp.rooms])
    lengths, depths = bounds[:, 2] - bounds[:, 0], bounds[:, 3] - bounds[:, 1]
    assert np.ptp(depths) < 1e-9 and np.ptp(lengths) < 1.0
    assert np.all((np.minimum(lengths, depths) > 10) & (np.minimum(lengths, depths) < 14))


def test_bays_congruent_with_exact_pitch(sb):
    fp = sb.floorplan
    np.testing.assert_allclose(fp.room_areas, fp.room_areas[0], rtol=0, atol=1e-9)
    cx = fp.room_centroids[:, 0]
    np.testing.assert_allclose(np.diff(cx), BAY_PITCH, atol=1e-9)
    assert BAY_PITCH == 7.30
    base = fp.rooms[0].polygon
    for k, room in enumerate(fp.rooms):
        moved = np.asarray(room.polygon.exterior.coords) - [k * BAY_PITCH, 0.0]
        assert base.equals_exact(type(base)(moved), tolerance=1e-9)
    # Doors at identical relative positions.
    rel = [d.segment.mean(0) - [(k + 1) * BAY_PITCH, 0] for k, d in enumerate(fp.doors)]
    np.testing.assert_allclose(np.asarray(rel) - rel[0], 0.0, atol=1e-9)


@pytest.mark.parametrize(
    "scene_fn,expected",
    [
        (three_rooms, [[1, 1, 0], [1, 1, 1], [0, 1, 1]]),
        (symmetric_bays, [[1, 1, 0, 0], [1, 1, 1, 0], [0, 1, 1, 1], [0, 0, 1, 1]]),
    ],
)
def test_door_adjacency(scene_fn, expected):
    fp = scene_fn().floorplan
    np.testing.assert_array_equal(fp.adjacency, np.array(expected, bool))


@pytest.mark.parametrize("scene_fn", [three_rooms, symmetric_bays])
def test_doors_are_real_openings_and_exterior_sealed(scene_fn):
    fp = scene_fn().floorplan
    for d in fp.doors:
        mid = d.segment.mean(0)
        assert not fp.wall_solid.contains(Point(mid)), "door centre must be open"
    # Sealed: the wall solid has no gap to the outside, so the footprint's exterior is
    # entirely wall (every room is a hole of the wall solid).
    solid = fp.wall_solid
    assert solid.geom_type == "Polygon"
    assert len(solid.interiors) >= 1


def test_clutter_not_in_floorplan(tr, sb):
    for scene in (tr, sb):
        assert scene.clutter.shape[1:] == (2, 2) and len(scene.clutter) > 0
        faces = {tuple(np.round(f, 6).ravel()) for f in scene.floorplan.wall_faces}
        assert not any(tuple(np.round(c, 6).ravel()) in faces for c in scene.clutter)
    # Clutter in every bay.
    mids = sb.clutter.mean(axis=1)
    rooms = set(sb.floorplan.room_at(mids)) - {None}
    assert rooms == {"R1", "R2", "R3", "R4"}
    # The as-built partition stub in 209 is more than 3 m long.
    assert np.max(np.linalg.norm(tr.clutter[:, 1] - tr.clutter[:, 0], axis=1)) > 3.0


@pytest.mark.parametrize("scene_fn", [three_rooms, symmetric_bays])
def test_trajectories_inside_and_clear_of_obstacles(scene_fn):
    scene = scene_fn()
    fp = scene.floorplan
    obstacles = [LineString(c) for c in scene.clutter]
    for name in scene.trajectories:
        xy = sample_path(scene.trajectories[name]).poses[:, :2]
        rooms = fp.room_at(xy)
        for p, r in zip(xy, rooms, strict=True):
            pt = Point(p)
            if r is None:  # only in a doorway
                assert min(pt.distance(LineString(d.segment)) for d in fp.doors) < 0.5, p
            assert fp.wall_solid.distance(pt) > 0.3, (name, p)
            assert min(o.distance(pt) for o in obstacles) > 0.3, (name, p)


def test_trajectory_room_orders(tr, sb):
    assert _room_sequence(tr, "T1") == ["209", "208", "207", "208", "209"]
    assert _room_sequence(tr, "T2") == ["207", "208", "209", "208"]
    for name in ("S1", "S2"):
        assert _room_sequence(sb, name) == ["R1", "R2", "R3", "R4"]
    np.testing.assert_allclose(
        np.linalg.norm(sb.trajectories["S2"][0] - sb.trajectories["S1"][0]), 0.3
    )


def test_trajectory_lengths(tr, sb):
    for name in ("T1", "T2"):
        s = sample_path(tr.trajectories[name]).s[-1]
        assert 50 <= s <= 70, (name, s)
    for name in ("S1", "S2"):
        assert sample_path(sb.trajectories[name]).s[-1] >= 28.0
