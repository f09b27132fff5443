"""GeoJSON without ``properties.kind`` (plain GIS exports) and plans in the wrong units."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mfcl_jax.cli import main
from mfcl_jax.floorplan import FloorplanError, floorplan_from_geojson, load_floorplan


def feat(gtype, coords, **props):
    return {
        "type": "Feature",
        "properties": props,
        "geometry": {"type": gtype, "coordinates": coords},
    }


def square(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]


def collection(*features, **top):
    return {"type": "FeatureCollection", "features": list(features), **top}


OUTLINE = feat("LineString", [[0, 0], [12, 0], [12, 6], [0, 6], [0, 0]], thickness=0.2)


def test_default_roles_without_kind():
    hall = [[square(4.1, 0.1, 7.9, 2.0)], [square(4.1, 2.2, 7.9, 5.9)]]
    data = collection(
        OUTLINE,
        feat("MultiLineString", [[[4, 0], [4, 2.5]], [[4, 3.5], [4, 6]]]),
        feat("Polygon", [square(0.1, 0.1, 3.9, 5.9)], name="Office"),
        feat("Polygon", [square(8.1, 0.1, 11.9, 5.9)]),
        feat("MultiPolygon", hall, name="Hall"),
        feat("LineString", [[4, 2.6], [4, 3.4]], kind="door", rooms=["Office", "Hall"]),
        feat("LineString", [[8, 1], [8, 1.8]], kind="door"),
    )
    fp = floorplan_from_geojson(data, source="qgis.geojson")
    assert fp.room_names == ("Office", "room_3", "Hall#1", "Hall#2")
    assert len(fp.walls) == 6 and np.allclose(fp.thickness[:4], 0.2)
    assert np.allclose(fp.thickness[4:], 0.15)  # the default thickness
    # The door naming "Hall" joins the part it touches (Hall#1 is 0.6 m away).
    assert fp.doors[0].rooms == ("Office", "Hall#2")
    # A door without rooms joins the rooms (parts) it touches.
    assert set(fp.doors[1].rooms) == {"room_3", "Hall#1"}
    assert fp.adjacency[fp.room_index("Office"), fp.room_index("Hall#2")]


def test_multi_part_room_door_far_from_every_part():
    data = collection(
        OUTLINE,
        feat(
            "MultiPolygon",
            [[square(0.1, 0.1, 2, 2)], [[[3, 3], [5, 3], [5, 5], [3, 5], [3, 3]]]],
            name="Hall",
        ),  # fmt: skip
        feat("Polygon", [square(8, 0.1, 11.9, 5.9)], name="Shop"),
        feat("LineString", [[8, 1], [8, 2]], kind="door", rooms=["Hall", "Shop"]),
    )
    with pytest.raises(FloorplanError) as e:
        floorplan_from_geojson(data, source="q.geojson")
    msg = str(e.value)
    assert (
        "q.geojson: feature #3 (door)" in msg and "multi-part room 'Hall' (Hall#1, Hall#2)" in msg
    )


def test_no_default_role_for_points():
    data = collection(OUTLINE, feat("Point", [1, 1]))
    with pytest.raises(
        FloorplanError,
        match=r"p\.geojson: feature #1: no properties.kind and geometry type 'Point'",
    ):
        floorplan_from_geojson(data, source="p.geojson")


def test_kind_errors_kept():
    for f, words in (
        (feat("MultiPolygon", [[square(0, 0, 1, 1)]], kind="room"), "expected Polygon"),
        (feat("Point", [1, 1], kind="wall"), "expected LineString or Polygon"),
        (feat("Polygon", [square(0, 0, 1, 1)], kind="window"), "properties.kind='window'"),
    ):
        with pytest.raises(FloorplanError, match=words):
            floorplan_from_geojson(collection(OUTLINE, f), source="k.geojson")


LON, LAT = 8.4044, 49.0069  # a building in Karlsruhe, in degrees


def _degrees():
    d = 0.0002
    return collection(
        feat("LineString", [[LON, LAT], [LON + d, LAT], [LON + d, LAT + d]], kind="wall"),
        feat("Polygon", [square(LON, LAT, LON + d, LAT + d)], kind="room", name="r"),
    )


def test_degrees_refused(tmp_path):
    p = tmp_path / "wgs84.geojson"
    p.write_text(json.dumps(_degrees()))
    before = p.read_text()
    with pytest.raises(FloorplanError) as e:
        load_floorplan(p)
    msg = str(e.value)
    assert "wgs84.geojson" in msg and "degrees, not metres" in msg and "extent 0.0002" in msg
    crs = {"type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}}
    metric = collection(OUTLINE, feat("Polygon", [square(1, 1, 3, 3)], name="r"), crs=crs)
    with pytest.raises(FloorplanError, match=r"crs 'urn:ogc:def:crs:OGC:1.3:CRS84' is longitude"):
        floorplan_from_geojson(metric, source="c.geojson")
    assert p.read_text() == before


def _millimetres(**top):
    return collection(
        feat("LineString", [[0, 0], [12000, 0], [12000, 6000], [0, 6000], [0, 0]], thickness=200),
        feat("Polygon", [square(100, 100, 5900, 5900)], name="a"),
        feat("Polygon", [square(6100, 100, 11900, 5900)], name="b"),
        **top,
    )


def test_millimetres_refused_unless_declared(tmp_path, capsys):
    p = tmp_path / "mm.geojson"
    p.write_text(json.dumps(_millimetres()))
    assert main(["floorplan", "show", str(p), "--out", str(tmp_path / "mm.png")]) == 2
    err = capsys.readouterr().err
    assert "mm.geojson" in err and "millimetres, not metres" in err and "thickness up to 200" in err
    assert not (tmp_path / "mm.png").exists()
    fp = floorplan_from_geojson(_millimetres(units="mm"), source="mm.geojson")
    np.testing.assert_allclose(fp.bounds, (-0.1, -0.1, 12.1, 6.1))
    np.testing.assert_allclose(fp.thickness, 0.2)
    fp = floorplan_from_geojson(_millimetres(properties={"units": "millimetres"}), source="x")
    assert abs(fp.room_areas.sum() - 2 * 5.8 * 5.8) < 1e-9
    with pytest.raises(FloorplanError, match=r"x\.geojson: units='feet' is not known"):
        floorplan_from_geojson(_millimetres(units="feet"), source="x.geojson")
