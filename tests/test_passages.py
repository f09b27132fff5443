"""Plans whose rooms meet without a door: open passages join them, and a plan of rooms only
gets walls along the rooms' free boundaries (``floorplan.passages``)."""

import json

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from mfcl_jax.floorplan import passages
from mfcl_jax.floorplan.geojson import load_geojson
from mfcl_jax.floorplan.model import Floorplan, Room


def _wall_line(x0, y0, x1, y1):
    return [[x0, y0], [x1, y1]]


def _two_rooms(gap: float):
    """Rooms A = [0, 5] x [0, 4] and B = [5.2, 10] x [0, 4] with a partition at x = 5.1 that
    leaves an opening of ``gap`` metres between y = 1 and 1 + gap (none when 0)."""
    a, b = box(0.1, 0.1, 5.0, 3.9), box(5.2, 0.1, 9.9, 3.9)
    walls = [_wall_line(0, 0, 10, 0), _wall_line(10, 0, 10, 4), _wall_line(10, 4, 0, 4),
             _wall_line(0, 4, 0, 0)]  # fmt: skip
    if gap > 0:
        walls += [_wall_line(5.1, 0, 5.1, 1.0), _wall_line(5.1, 1.0 + gap, 5.1, 4.0)]
    else:
        walls += [_wall_line(5.1, 0, 5.1, 4.0)]
    return Floorplan(walls=np.asarray(walls, float), thickness=0.2,
                     rooms=[Room("A", a), Room("B", b)])  # fmt: skip


@pytest.mark.parametrize("gap, joined", [(0.0, False), (0.3, False), (1.0, True), (2.5, True)])
def test_a_wall_gap_wide_enough_for_a_person_joins_two_rooms(gap, joined):
    fp = _two_rooms(gap)
    assert not fp.doors
    assert bool(fp.adjacency[0, 1]) is joined
    assert bool(fp.adjacency[1, 0]) is joined


def test_rooms_far_apart_are_not_joined_and_the_diagonal_holds():
    rooms = [Room("A", box(0, 0, 4, 4)), Room("B", box(6, 0, 10, 4))]
    walls = np.asarray([_wall_line(-0.1, -0.1, 10.1, -0.1)], float)
    fp = Floorplan(walls=walls, thickness=0.1, rooms=rooms)
    assert fp.adjacency.tolist() == [[True, False], [False, True]]


def test_a_ring_corridor_opening_into_a_lobby_without_a_door_is_joined():
    ring = Polygon(box(0, 0, 20, 20).exterior.coords, [box(4, 4, 16, 16).exterior.coords])
    lobby = box(20.1, 6, 26, 14)  # touches the ring's east side along 8 m, nothing between
    walls = np.asarray([_wall_line(0, 0, 20, 0), _wall_line(0, 20, 20, 20)], float)
    fp = Floorplan(walls=walls, thickness=0.1, rooms=[Room("ring", ring), Room("lobby", lobby)])
    assert fp.adjacency[0, 1] and fp.adjacency[1, 0]


def test_a_plan_of_rooms_only_gets_walls_along_the_free_boundaries():
    a, b = box(0, 0, 5, 4), box(5, 0, 10, 4)  # share the edge x = 5
    fp = Floorplan(walls=np.zeros((0, 2, 2)), thickness=0.1, rooms=[Room("A", a), Room("B", b)])
    assert fp.walls_derived
    assert len(fp.walls) > 0
    mids = fp.walls.mean(axis=1)
    # no wall drawn along the shared edge, walls all around the outside
    assert not np.any(np.abs(mids[:, 0] - 5.0) < 0.3), mids
    assert np.any(np.abs(mids[:, 1] - 0.0) < 1e-6) and np.any(np.abs(mids[:, 1] - 4.0) < 1e-6)
    assert fp.adjacency[0, 1]
    # the outer boundary is closed: a point outside both rooms is outside, inside is inside
    r = fp.rasterize()
    ij = lambda x, y: (int((y - r.origin[1]) / r.res), int((x - r.origin[0]) / r.res))  # noqa: E731
    assert np.asarray(r.inside)[ij(2.5, 2.0)] and np.asarray(r.inside)[ij(7.5, 2.0)]
    assert np.asarray(r.wall)[ij(2.5, 0.0)]


def test_a_plan_with_walls_keeps_them_as_given():
    fp = _two_rooms(0.0)
    assert not fp.walls_derived
    assert len(fp.walls) == 5


def test_walls_from_rooms_of_rooms_that_do_not_meet_draw_every_boundary():
    segs = passages.walls_from_rooms([box(0, 0, 4, 4), box(6, 0, 10, 4)])
    assert len(segs) == 8
    assert np.isclose(np.hypot(*(segs[:, 1] - segs[:, 0]).T).sum(), 32.0)


def test_a_rooms_only_geojson_loads(tmp_path):
    feats = [
        {"type": "Feature", "properties": {"kind": "room", "name": n},
         "geometry": {"type": "Polygon", "coordinates": [list(map(list, p.exterior.coords))]}}
        for n, p in (("A", box(0, 0, 5, 4)), ("B", box(5, 0, 10, 4)))
    ]  # fmt: skip
    path = tmp_path / "rooms.geojson"
    path.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    fp = load_geojson(path)
    assert fp.walls_derived and len(fp.walls) > 0
    assert fp.adjacency[0, 1]


def test_a_plan_without_rooms_or_walls_still_fails_clearly():
    with pytest.raises(Exception, match="no rooms"):
        Floorplan(walls=np.zeros((0, 2, 2)), thickness=0.1, rooms=[])


def test_a_rooms_only_plan_keeps_the_wall_between_rooms_that_face_across_it():
    # two offices 0.2 m apart (a partition's thickness) and a hall sharing an edge with A
    a, b, hall = box(0, 0, 5, 4), box(5.2, 0, 10, 4), box(0, 4, 4.5, 8)
    rooms = [Room("A", a), Room("B", b), Room("hall", hall)]
    fp = Floorplan(walls=np.zeros((0, 2, 2)), thickness=0.1, rooms=rooms)
    r = fp.rasterize()
    ij = lambda x, y: (int((y - r.origin[1]) / r.res), int((x - r.origin[0]) / r.res))  # noqa: E731
    wall = np.asarray(r.wall)
    # the partition is a wall along its whole length, on both faces
    assert all(wall[ij(5.0, y)] and wall[ij(5.2, y)] for y in np.arange(0.3, 3.8, 0.25))
    # the shared edge y = 4 between A and the hall is open, the hall's far side is a wall
    assert not any(wall[ij(x, 4.0)] for x in np.arange(0.3, 4.3, 0.25))
    assert wall[ij(2.5, 8.0)]
    # no door is marked: rooms facing across a wall may be joined anywhere on it, shared
    # edges join, and B and the hall (0.7 m apart at their nearest) are not joined
    assert fp.adjacency[0, 1] and fp.adjacency[0, 2] and not fp.adjacency[1, 2]


def _rooms_only_geojson(path, x0: float) -> None:
    """Two offices 0.2 m apart (a partition) starting at ``x0``, rooms only."""
    feats = [
        {"type": "Feature", "properties": {"kind": "room", "name": n},
         "geometry": {"type": "Polygon", "coordinates": [list(map(list, p.exterior.coords))]}}
        for n, p in (("A", box(x0, 0, x0 + 5, 4)), ("B", box(x0 + 5.2, 0, x0 + 10, 4)))
    ]  # fmt: skip
    path.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))


def test_a_georeferenced_rooms_only_plan_keeps_its_rooms_joined_and_says_what_was_derived(
    tmp_path,
):
    from mfcl_jax.floorplan import FloorplanWarning
    from mfcl_jax.floorplan.geojson_write import save_geojson
    from mfcl_jax.floorplan.load import load_floorplan

    src = tmp_path / "rooms.geojson"
    _rooms_only_geojson(src, 500_000.0)  # far from the origin: the loader moves it
    with pytest.warns(FloorplanWarning, match="rooms and no walls"):
        fp = load_floorplan(src)
    assert fp.offset[0] != 0.0
    # moved, its walls are still the rooms' own: the two offices may be joined across theirs
    assert fp.walls_derived and fp.adjacency[0, 1]
    # written and read back, it is the same plan of rooms only
    out = save_geojson(fp, tmp_path / "again.geojson")
    kinds = [f["properties"]["kind"] for f in json.loads(out.read_text())["features"]]
    assert kinds == ["room", "room"]
    with pytest.warns(FloorplanWarning):
        again = load_floorplan(out)
    assert again.walls_derived and again.adjacency[0, 1]
    assert len(again.walls) == len(fp.walls)
