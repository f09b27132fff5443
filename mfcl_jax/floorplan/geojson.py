"""GeoJSON floor plans (the interchange format of ARCHITECTURE.md).

A ``FeatureCollection`` in metres; each feature's ``properties.kind`` is
``wall`` (LineString centre line with optional ``thickness``, or Polygon footprint),
``room`` (Polygon with ``name``) or ``door`` (LineString across the opening, ``rooms: [a, b]``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from shapely.geometry import Polygon

from mfcl_jax.floorplan.model import DEFAULT_WALL_THICKNESS, Door, Floorplan, FloorplanError, Room
from mfcl_jax.io.atomic import atomic_write

__all__ = ["load_geojson", "save_geojson", "floorplan_from_geojson", "floorplan_to_geojson"]


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


def floorplan_from_geojson(data: dict, source: str = "<geojson>", name: str | None = None):
    """Builds a ``Floorplan`` from a parsed GeoJSON FeatureCollection.

    Raises:
        FloorplanError: naming the source, the feature index and what is wrong.
    """
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection":
        raise FloorplanError(f"{source}: top level must be a GeoJSON FeatureCollection")
    feats = data.get("features")
    if not isinstance(feats, list):
        raise FloorplanError(f"{source}: 'features' must be a list")
    walls, thick, wall_polys, rooms, doors = [], [], [], [], []
    for i, f in enumerate(feats):
        props = f.get("properties") or {}
        kind = props.get("kind")
        gtype = (f.get("geometry") or {}).get("type")
        if kind == "wall":
            t = props.get("thickness", DEFAULT_WALL_THICKNESS)
            try:
                t = float(t)
            except (TypeError, ValueError):
                raise FloorplanError(f"{source}: feature #{i} (wall): thickness={t!r}") from None
            if not (np.isfinite(t) and t > 0):
                raise FloorplanError(f"{source}: feature #{i} (wall): thickness={t!r} must be > 0")
            if gtype == "LineString":
                xy = _coords(source, i, f, "wall")[:, :2]
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
        elif kind == "room":
            if gtype != "Polygon":
                raise FloorplanError(
                    f"{source}: feature #{i} (room): geometry type {gtype!r}, expected Polygon"
                )
            rname = str(props.get("name", f"room{i}"))
            rings = _rings(source, i, f"room {rname!r}", f)
            poly = Polygon(rings[0], rings[1:])
            if not poly.is_valid:
                raise FloorplanError(
                    f"{source}: feature #{i} (room {rname!r}): polygon is self-intersecting "
                    "or otherwise invalid"
                )
            rooms.append(Room(rname, poly))
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
    # Doors without explicit rooms join the rooms they touch.
    room_objs = {r.name: r for r in rooms}
    door_objs = []
    from shapely.geometry import LineString

    for i, xy, names in doors:
        if names is None:
            line = LineString(xy)
            names = [r.name for r in rooms if r.polygon.distance(line) <= 0.5][:2]
            if not names:
                raise FloorplanError(f"{source}: feature #{i} (door): touches no room")
        if not isinstance(names, list | tuple) or not 1 <= len(names) <= 2:
            raise FloorplanError(f"{source}: feature #{i} (door): rooms={names!r}, expected [a, b]")
        for n in names:
            if str(n) not in room_objs:
                raise FloorplanError(f"{source}: feature #{i} (door): unknown room {n!r}")
        door_objs.append(Door(xy, tuple(str(n) for n in names)))
    return Floorplan(
        walls=np.asarray(walls, float).reshape(-1, 2, 2),
        thickness=np.asarray(thick, float),
        rooms=tuple(rooms),
        doors=tuple(door_objs),
        wall_polygons=tuple(wall_polys),
        name=name or data.get("name") or Path(str(source)).stem,
        source=str(source),
    )


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


def _poly_coords(poly: Polygon) -> list:
    return [np.asarray(poly.exterior.coords).tolist()] + [
        np.asarray(r.coords).tolist() for r in poly.interiors
    ]


def floorplan_to_geojson(fp: Floorplan) -> dict:
    """The GeoJSON FeatureCollection for a floor plan."""
    feats = []
    for seg, t in zip(fp.walls, fp.thickness, strict=True):
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "wall", "thickness": float(t)},
                "geometry": {"type": "LineString", "coordinates": seg.tolist()},
            }
        )
    for poly in fp.wall_polygons:
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "wall"},
                "geometry": {"type": "Polygon", "coordinates": _poly_coords(poly)},
            }
        )
    for r in fp.rooms:
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "room", "name": r.name},
                "geometry": {"type": "Polygon", "coordinates": _poly_coords(r.polygon)},
            }
        )
    for d in fp.doors:
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "door", "rooms": list(d.rooms)},
                "geometry": {"type": "LineString", "coordinates": np.asarray(d.segment).tolist()},
            }
        )
    return {"type": "FeatureCollection", "name": fp.name, "features": feats}


def save_geojson(fp: Floorplan, path) -> Path:
    """Writes a floor plan atomically (a temporary file renamed into place)."""
    path = atomic_write(path, json.dumps(floorplan_to_geojson(fp), indent=1))
    return path
