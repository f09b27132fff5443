"""GeoJSON floor plans (the interchange format of ARCHITECTURE.md).

A ``FeatureCollection`` in metres (other units: ``mfcl_jax.floorplan.geojson_units``); each
feature's ``properties.kind`` is ``wall`` (LineString centre line with optional
``thickness``, or Polygon footprint), ``room`` (Polygon with ``name``) or ``door``
(LineString across the opening, ``rooms: [a, b]``; without ``rooms`` it joins the rooms it
touches).

Features without ``kind`` (a plain GIS export, e.g. from QGIS) take a default role from
their geometry: Polygon -> room (named by ``properties.name``, else ``room_<i>`` with ``i``
the feature index), MultiPolygon -> one room per part, named ``<name>#1``, ``<name>#2``, ...,
LineString/MultiLineString -> wall centre lines (``thickness`` or the default). A door that
names a multi-part room joins the part it touches (the nearest one if it touches several).
Doors cannot be guessed from geometry: they need ``kind: door``. Other geometries without
``kind`` are an error.

The collection's optional member ``"outside": "unknown"`` marks a plan whose outside was never
observed (an occupancy map's, ``Floorplan.outside_unknown``); absent or ``"building"``, the
outside is outdoors. Coordinates are read in float64. Writing: ``geojson_write``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from shapely.geometry import LineString, Polygon

from mfcl_jax.floorplan.geojson_units import metre_scale, scaled
from mfcl_jax.floorplan.model import (
    DEFAULT_WALL_THICKNESS,
    DOOR_TOUCH_TOL,
    Door,
    Floorplan,
    FloorplanError,
    Room,
)

__all__ = ["load_geojson", "floorplan_from_geojson"]


def _coords(src, i, feat, shape_desc):
    try:
        arr = np.asarray(feat["geometry"]["coordinates"], dtype=float)
    except (KeyError, TypeError, ValueError) as e:
        raise FloorplanError(f"{src}: feature #{i}: bad geometry.coordinates ({e})") from None
    if not np.all(np.isfinite(arr)):
        raise FloorplanError(f"{src}: feature #{i} ({shape_desc}): non-finite coordinates")
    return arr


def _ring(src, i, what, ring) -> np.ndarray:
    try:
        ring = np.asarray(ring, dtype=float)
    except (TypeError, ValueError) as e:
        raise FloorplanError(f"{src}: feature #{i} ({what}): bad polygon ring ({e})") from None
    if ring.ndim != 2 or ring.shape[1] < 2 or len(ring) < 4:
        raise FloorplanError(f"{src}: feature #{i} ({what}): a polygon ring needs >= 4 positions")
    if not np.all(np.isfinite(ring)):
        raise FloorplanError(f"{src}: feature #{i} ({what}): non-finite coordinates")
    if not np.allclose(ring[0, :2], ring[-1, :2]):
        raise FloorplanError(
            f"{src}: feature #{i} ({what}): polygon ring is not closed "
            f"(first {ring[0, :2].tolist()} != last {ring[-1, :2].tolist()})"
        )
    return ring[:, :2]


def _rings(src, i, what, feat) -> list[np.ndarray]:
    rings = (feat.get("geometry") or {}).get("coordinates")
    if not isinstance(rings, list) or not rings:
        raise FloorplanError(f"{src}: feature #{i} ({what}): Polygon needs a list of rings")
    return [_ring(src, i, what, r) for r in rings]


def _wall(source, i, f, gtype, props, walls, thick, wall_polys) -> None:
    t = props.get("thickness", DEFAULT_WALL_THICKNESS)
    try:
        t = float(t)
    except (TypeError, ValueError):
        raise FloorplanError(f"{source}: feature #{i} (wall): thickness={t!r}") from None
    if not (np.isfinite(t) and t > 0):
        raise FloorplanError(f"{source}: feature #{i} (wall): thickness={t!r} must be > 0")
    if gtype in ("LineString", "MultiLineString"):
        arr = _coords(source, i, f, "wall")
        for line in arr if gtype == "MultiLineString" else [arr]:
            xy = np.asarray(line, float).reshape(len(line), -1)[:, :2]
            if len(xy) < 2:
                raise FloorplanError(f"{source}: feature #{i} (wall): needs >= 2 positions")
            for a, b in zip(xy[:-1], xy[1:], strict=True):
                walls.append([a, b])
                thick.append(t)
    elif gtype == "Polygon":
        rings = _rings(source, i, "wall", f)
        poly = Polygon(rings[0], rings[1:])
        if not poly.is_valid:
            raise FloorplanError(f"{source}: feature #{i} (wall): invalid polygon")
        wall_polys.append(poly)
    else:
        raise FloorplanError(
            f"{source}: feature #{i} (wall): geometry type {gtype!r}, "
            "expected LineString or Polygon"
        )


def _room(source, i, rname, rings) -> Room:
    poly = Polygon(rings[0], rings[1:])
    if not poly.is_valid:
        raise FloorplanError(
            f"{source}: feature #{i} (room {rname!r}): polygon is self-intersecting "
            "or otherwise invalid"
        )
    return Room(rname, poly)


def _multi_room(source, i, f, rname) -> list[Room]:
    parts = (f.get("geometry") or {}).get("coordinates")
    if not isinstance(parts, list) or not parts:
        raise FloorplanError(f"{source}: feature #{i} (room {rname!r}): empty MultiPolygon")
    out = []
    for k, rings in enumerate(parts, 1):
        name = f"{rname}#{k}"
        if not isinstance(rings, list) or not rings:
            raise FloorplanError(f"{source}: feature #{i} (room {name!r}): part has no rings")
        out.append(_room(source, i, name, [_ring(source, i, f"room {name!r}", r) for r in rings]))
    return out


def _default_kind(source, i, gtype) -> str:
    if gtype in ("Polygon", "MultiPolygon"):
        return "room"
    if gtype in ("LineString", "MultiLineString"):
        return "wall"
    raise FloorplanError(
        f"{source}: feature #{i}: no properties.kind and geometry type {gtype!r} has no default "
        "role (Polygon/MultiPolygon are rooms, LineString/MultiLineString are walls)"
    )


def floorplan_from_geojson(data: dict, source: str = "<geojson>", name: str | None = None):
    """Builds a ``Floorplan`` from a parsed GeoJSON FeatureCollection (module rules).

    Raises:
        FloorplanError: naming the source, the feature index and what is wrong.
    """
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection":
        raise FloorplanError(f"{source}: top level must be a GeoJSON FeatureCollection")
    feats = data.get("features")
    if not isinstance(feats, list):
        raise FloorplanError(f"{source}: 'features' must be a list")
    data = scaled(data, metre_scale(data, source))
    feats = data["features"]
    walls, thick, wall_polys, rooms, doors = [], [], [], [], []
    parts: dict[str, list[str]] = {}
    for i, f in enumerate(feats):
        if not isinstance(f, dict):
            raise FloorplanError(f"{source}: feature #{i}: not a GeoJSON Feature object")
        props = f.get("properties") or {}
        kind = props.get("kind")
        gtype = (f.get("geometry") or {}).get("type")
        if kind is None:
            kind = _default_kind(source, i, gtype)
            if gtype == "MultiPolygon":
                rname = str(props.get("name", f"room_{i}"))
                split = _multi_room(source, i, f, rname)
                parts[rname] = [r.name for r in split]
                rooms.extend(split)
                continue
            props = dict(props, name=props.get("name", f"room_{i}"))
        if kind == "wall":
            _wall(source, i, f, gtype, props, walls, thick, wall_polys)
        elif kind == "room":
            if gtype != "Polygon":
                raise FloorplanError(
                    f"{source}: feature #{i} (room): geometry type {gtype!r}, expected Polygon"
                )
            rname = str(props.get("name", f"room{i}"))
            rooms.append(_room(source, i, rname, _rings(source, i, f"room {rname!r}", f)))
        elif kind == "door":
            if gtype != "LineString":
                raise FloorplanError(
                    f"{source}: feature #{i} (door): geometry type {gtype!r}, expected LineString"
                )
            xy = _coords(source, i, f, "door")[:, :2]
            if len(xy) != 2:
                raise FloorplanError(f"{source}: feature #{i} (door): needs exactly 2 positions")
            doors.append((i, xy, props.get("rooms")))
        else:
            raise FloorplanError(
                f"{source}: feature #{i}: properties.kind={kind!r}, expected wall, room or door"
            )
    if not rooms:
        raise FloorplanError(f"{source}: no 'room' features: a floor plan needs named rooms")
    outside = data.get("outside", "building")
    if outside not in ("building", "unknown"):
        raise FloorplanError(
            f"{source}: 'outside' is {outside!r}, expected 'building' or 'unknown'"
        )
    return Floorplan(
        walls=np.asarray(walls, float).reshape(-1, 2, 2),
        thickness=np.asarray(thick, float),
        rooms=tuple(rooms),
        doors=tuple(_doors(source, doors, rooms, parts)),
        wall_polygons=tuple(wall_polys),
        name=name or data.get("name") or Path(str(source)).stem,
        source=str(source),
        outside_unknown=outside == "unknown",
    )


def _doors(source, doors, rooms, parts) -> list[Door]:
    """Doors with their room names resolved: none given -> the rooms the door touches; a
    multi-part room's name -> the part the door touches (the nearest, if several)."""
    room_objs = {r.name: r for r in rooms}
    out = []
    for i, xy, names in doors:
        line = LineString(xy)
        if names is None:
            names = [r.name for r in rooms if r.polygon.distance(line) <= DOOR_TOUCH_TOL][:2]
            if not names:
                raise FloorplanError(f"{source}: feature #{i} (door): touches no room")
        if not isinstance(names, list | tuple) or not 1 <= len(names) <= 2:
            raise FloorplanError(f"{source}: feature #{i} (door): rooms={names!r}, expected [a, b]")
        resolved = []
        for n in (str(v) for v in names):
            if n in parts and n not in room_objs:
                dist = {p: room_objs[p].polygon.distance(line) for p in parts[n]}
                best = min(dist, key=dist.get)
                if dist[best] > DOOR_TOUCH_TOL:
                    raise FloorplanError(
                        f"{source}: feature #{i} (door): touches no part of the multi-part room "
                        f"{n!r} ({', '.join(parts[n])})"
                    )
                n = best
            if n not in room_objs:
                raise FloorplanError(f"{source}: feature #{i} (door): unknown room {n!r}")
            resolved.append(n)
        out.append(Door(xy, tuple(resolved)))
    return out


def load_geojson(path) -> Floorplan:
    """Reads a GeoJSON floor plan file."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise FloorplanError(f"{path}: file not found") from None
    except json.JSONDecodeError as e:
        raise FloorplanError(f"{path}: not valid JSON ({e})") from None
    return floorplan_from_geojson(data, source=str(path))
