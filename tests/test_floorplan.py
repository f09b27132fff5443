"""Floor-plan model: GeoJSON round trip, rasters, room graph and every bad-input case."""

import json

import numpy as np
import pytest
from shapely.geometry import box

from mfcl_jax.floorplan import (
    Door,
    Floorplan,
    FloorplanError,
    Room,
    floorplan_from_geojson,
    floorplan_to_geojson,
    load_geojson,
    save_geojson,
)


def two_rooms(**kw):
    walls = np.array(
        [
            [[0, 0], [10, 0]],
            [[10, 0], [10, 8]],
            [[10, 8], [0, 8]],
            [[0, 8], [0, 0]],
            [[5, 0], [5, 3.5]],
            [[5, 4.5], [5, 8]],
        ],
        float,
    )
    rooms = (Room("a", box(0.1, 0.1, 4.9, 7.9)), Room("b", box(5.1, 0.1, 9.9, 7.9)))
    doors = (Door(np.array([[5, 3.5], [5, 4.5]]), ("a", "b")),)
    args = dict(walls=walls, thickness=0.2, rooms=rooms, doors=doors, name="two")
    args.update(kw)
    return Floorplan(**args)


def test_geojson_round_trip(tmp_path):
    fp = two_rooms()
    path = save_geojson(fp, tmp_path / "fp.geojson")
    fp2 = load_geojson(path)
    assert fp2.room_names == fp.room_names
    assert np.allclose(fp2.walls, fp.walls) and np.allclose(fp2.thickness, fp.thickness)
    assert np.array_equal(fp2.adjacency, fp.adjacency)
    assert fp2.wall_solid.symmetric_difference(fp.wall_solid).area < 1e-9
    r1, r2 = fp.rasterize(), fp2.rasterize()
    assert np.array_equal(r1.room_id, r2.room_id) and np.allclose(r1.dist, r2.dist)
    assert not list(tmp_path.glob(".*tmp"))  # atomic write leaves no temporary file
    # an occupancy map's never-observed outside survives the round trip; a plan's stays outdoors
    assert not fp2.outside_unknown and float(r2.outside) == 1.0
    m = load_geojson(save_geojson(two_rooms(outside_unknown=True), tmp_path / "m.geojson"))
    assert m.outside_unknown and float(m.rasterize().outside) == 0.5
    data = json.loads((tmp_path / "m.geojson").read_text())
    data["outside"] = "space"
    with pytest.raises(FloorplanError, match="'outside' is 'space'"):
        floorplan_from_geojson(data, source="m.geojson")


def test_rasters():
    fp = two_rooms()
    r = fp.rasterize(res=0.1)
    assert r.res == 0.1

    # Room ids at room centres; walls are -1 and have zero distance.
    def cell(x, y):
        ix = int((x - r.origin[0]) / r.res)
        iy = int((y - r.origin[1]) / r.res)
        return iy, ix

    assert r.room_id[cell(2.5, 4.0)] == 0 and r.room_id[cell(7.5, 4.0)] == 1
    assert r.wall[cell(5.0, 1.0)] and r.room_id[cell(5.0, 1.0)] == -1
    assert r.dist[cell(5.0, 1.0)] == 0.0
    # Distance from the middle of room a to its nearest wall face (x=0.1 or 4.9): ~2.4 m.
    assert abs(r.dist[cell(2.55, 4.05)] - 2.4) < 0.15
    assert r.inside[cell(2.5, 4.0)] and not r.inside[cell(-0.5, -0.5)]
    assert r.adjacency.tolist() == [[True, True], [True, True]]


@pytest.mark.parametrize("thickness", [0.1, 0.04])
def test_thin_wall_on_cell_borders_is_not_lost(thickness):
    # A 0.10 m wall whose faces sit on cell-centre rows holds no cell centre (and a 0.04 m one
    # may hold none): the rasters must still carry it along its whole length (the walls a plan
    # of rooms only draws are 0.10 m thick).
    outer = [[[0, 0], [10, 0]], [[0, 0], [0, 8]], [[10, 0], [10, 8]], [[0, 8], [10, 8]]]
    walls = np.array([*outer, [[5.05, 0], [5.05, 8]]], float)
    fp = Floorplan(walls=walls, thickness=np.r_[[0.3] * 4, thickness],
                   rooms=(Room("a", box(0.2, 0.2, 9.8, 7.8)),), name="thin")  # fmt: skip
    r = fp.rasterize(res=0.1)
    ys = r.origin[1] + r.res * (np.arange(r.shape[0]) + 0.5)
    rows = (ys > 0.3) & (ys < 7.7)
    xs = r.origin[0] + r.res * (np.arange(r.shape[1]) + 0.5)
    near = np.abs(xs - 5.05) < 0.1
    assert np.asarray(r.wall)[rows][:, near].any(axis=1).all()
    assert (np.asarray(r.dist)[rows][:, near].min(axis=1) == 0).all()
    away = (np.abs(xs - 5.05) > 0.2) & (xs > 1) & (xs < 9)
    assert not np.asarray(r.wall)[rows][:, away].any()  # and no thicker


def test_adjacency_from_doors_and_open_passages():
    assert two_rooms().adjacency.tolist() == [[True, True], [True, True]]
    # without the door feature, the 1 m gap in the partition is still an open passage
    assert two_rooms(doors=()).adjacency.tolist() == [[True, True], [True, True]]
    closed = np.concatenate([two_rooms().walls[:4], [[[5, 0], [5, 8]]]])
    fp = two_rooms(doors=(), walls=closed, thickness=0.2)
    assert fp.adjacency.tolist() == [[True, False], [False, True]]


def test_corners_and_faces():
    fp = two_rooms()
    pts, dirs = fp.corners
    assert pts.shape[1] == 2 and dirs.shape == (len(pts), 2)
    # The outer corner of the building is a corner.
    assert np.min(np.linalg.norm(pts - np.array([-0.1, -0.1]), axis=1)) < 1e-6
    assert fp.wall_faces.shape[1:] == (2, 2)


def test_transformed_moves_everything():
    fp = two_rooms()
    g = (3.0, -2.0, 0.7)
    moved = fp.transformed(g)
    c, s = np.cos(0.7), np.sin(0.7)
    p = fp.room_centroids[0]
    expect = np.array([c * p[0] - s * p[1] + 3.0, s * p[0] + c * p[1] - 2.0])
    assert np.allclose(moved.room_centroids[0], expect)
    assert abs(moved.wall_solid.area - fp.wall_solid.area) < 1e-6


def collection(*features):
    return {"type": "FeatureCollection", "features": list(features)}


def room_feature(name, ring):
    return {
        "type": "Feature",
        "properties": {"kind": "room", "name": name},
        "geometry": {"type": "Polygon", "coordinates": [ring]},
    }


WALL = {
    "type": "Feature",
    "properties": {"kind": "wall", "thickness": 0.2},
    "geometry": {"type": "LineString", "coordinates": [[0, 0], [5, 0]]},
}
SQUARE = [[0, 0], [4, 0], [4, 4], [0, 4], [0, 0]]


def test_bad_no_rooms():
    with pytest.raises(FloorplanError, match="no 'room' features"):
        floorplan_from_geojson(collection(WALL), source="x.geojson")


def test_bad_unclosed_polygon():
    with pytest.raises(FloorplanError, match=r"feature #1 \(room 'r1'\).*not closed"):
        floorplan_from_geojson(collection(WALL, room_feature("r1", SQUARE[:-1] + [[0, 1]])))


def test_bad_self_intersecting_polygon():
    bowtie = [[0, 0], [4, 4], [4, 0], [0, 4], [0, 0]]
    with pytest.raises(FloorplanError, match="room 'bow'.*self-intersecting"):
        floorplan_from_geojson(collection(WALL, room_feature("bow", bowtie)))


def test_bad_door_touching_no_room():
    door = {
        "type": "Feature",
        "properties": {"kind": "door"},
        "geometry": {"type": "LineString", "coordinates": [[40, 40], [41, 40]]},
    }
    with pytest.raises(FloorplanError, match=r"feature #2 \(door\): touches no room"):
        floorplan_from_geojson(collection(WALL, room_feature("r", SQUARE), door))


def test_bad_door_named_room_far_away():
    fp = two_rooms()
    with pytest.raises(FloorplanError, match="door #0: does not touch room 'a'"):
        Floorplan(
            walls=fp.walls,
            thickness=0.2,
            rooms=fp.rooms,
            doors=(Door(np.array([[30.0, 30.0], [31.0, 30.0]]), ("a", "b")),),
        )


def test_bad_nan_coordinates():
    bad = room_feature("n", [[0, 0], [4, 0], [float("nan"), 4], [0, 4], [0, 0]])
    with pytest.raises(FloorplanError, match=r"feature #1 \(room 'n'\): non-finite"):
        floorplan_from_geojson(collection(WALL, bad))


def test_bad_nan_in_file(tmp_path):
    p = tmp_path / "nan.geojson"
    text = json.dumps(collection(WALL, room_feature("r", SQUARE))).replace("[5, 0]", "[NaN, 0]")
    p.write_text(text)
    with pytest.raises(FloorplanError, match=r"nan.geojson: feature #0 \(wall\): non-finite"):
        load_geojson(p)


def test_bad_kind_and_json(tmp_path):
    feat = dict(WALL, properties={"kind": "window"})
    with pytest.raises(FloorplanError, match="properties.kind='window'"):
        floorplan_from_geojson(collection(feat, room_feature("r", SQUARE)))
    p = tmp_path / "broken.geojson"
    p.write_text("{not json")
    with pytest.raises(FloorplanError, match="broken.geojson: not valid JSON"):
        load_geojson(p)
    with pytest.raises(FloorplanError, match="file not found"):
        load_geojson(tmp_path / "missing.geojson")


def test_bad_model_level_errors():
    fp = two_rooms()
    with pytest.raises(FloorplanError, match="no rooms"):
        Floorplan(walls=fp.walls, thickness=0.2, rooms=())
    # rooms only: the walls are drawn along the rooms' free boundaries, not refused
    assert Floorplan(walls=np.zeros((0, 2, 2)), thickness=0.2, rooms=fp.rooms).walls_derived
    with pytest.raises(FloorplanError, match="duplicate room name"):
        Floorplan(walls=fp.walls, thickness=0.2, rooms=(fp.rooms[0], fp.rooms[0]))
    with pytest.raises(FloorplanError, match="wall #1: thickness"):
        Floorplan(walls=fp.walls, thickness=[0.2, -1, 0.2, 0.2, 0.2, 0.2], rooms=fp.rooms)


def test_geojson_schema_matches_architecture():
    data = floorplan_to_geojson(two_rooms())
    kinds = {f["properties"]["kind"] for f in data["features"]}
    assert kinds == {"wall", "room", "door"}
    door = next(f for f in data["features"] if f["properties"]["kind"] == "door")
    assert door["properties"]["rooms"] == ["a", "b"]


def test_round_trip_room_with_hole_and_polygon_wall(tmp_path):
    """Rings of different lengths (a courtyard hole) must load; IFC exports produce them."""
    from shapely.geometry import Polygon

    outer = [(0.1, 0.1), (9.9, 0.1), (9.9, 7.9), (0.1, 7.9)]
    hole = [(4.0, 3.0), (5.0, 3.0), (5.0, 4.0)]
    wall_poly = Polygon(
        [(-0.5, -0.5), (10.5, -0.5), (10.5, 8.5), (-0.5, 8.5)],
        [[(-0.1, -0.1), (10.1, -0.1), (10.1, 8.1), (-0.1, 8.1)]],
    )
    fp = Floorplan(
        walls=np.zeros((0, 2, 2)),
        thickness=0.2,
        rooms=(Room("c", Polygon(outer, [hole])),),
        wall_polygons=(wall_poly,),
    )
    fp2 = load_geojson(save_geojson(fp, tmp_path / "hole.geojson"))
    assert abs(fp2.room("c").polygon.area - fp.room("c").polygon.area) < 1e-9
    assert len(fp2.room("c").polygon.interiors) == 1
