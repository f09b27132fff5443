"""Writing floor plans as GeoJSON (the format ``geojson`` reads).

Saving writes plan-frame coordinates (``Floorplan.offset`` added back), so a plan moved to a
local origin saves as it was read; an occupancy map's plan keeps its never-observed outside
(the collection's ``"outside": "unknown"``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from shapely.geometry import Polygon

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.io.atomic import atomic_write

__all__ = ["save_geojson", "floorplan_to_geojson"]


def _poly_coords(poly: Polygon, off: np.ndarray) -> list:
    return [(np.asarray(poly.exterior.coords) + off).tolist()] + [
        (np.asarray(r.coords) + off).tolist() for r in poly.interiors
    ]


def floorplan_to_geojson(fp: Floorplan) -> dict:
    """The GeoJSON FeatureCollection for a floor plan, in plan-frame coordinates. A plan of
    rooms only is written as it came, without the walls derived from its rooms (read back,
    they are derived again; written out, they would read as a plan whose walls are given)."""
    off = np.asarray(fp.offset, np.float64)
    feats = []
    walls = () if fp.walls_derived else zip(fp.walls, fp.thickness, strict=True)
    for seg, t in walls:
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "wall", "thickness": float(t)},
                "geometry": {"type": "LineString", "coordinates": (seg + off).tolist()},
            }
        )
    for poly in fp.wall_polygons:
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "wall"},
                "geometry": {"type": "Polygon", "coordinates": _poly_coords(poly, off)},
            }
        )
    for r in fp.rooms:
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "room", "name": r.name},
                "geometry": {"type": "Polygon", "coordinates": _poly_coords(r.polygon, off)},
            }
        )
    for d in fp.doors:
        seg = np.asarray(d.segment, np.float64) + off
        feats.append(
            {
                "type": "Feature",
                "properties": {"kind": "door", "rooms": list(d.rooms)},
                "geometry": {"type": "LineString", "coordinates": seg.tolist()},
            }
        )
    out = {"type": "FeatureCollection", "name": fp.name, "features": feats}
    if fp.outside_unknown:
        out["outside"] = "unknown"  # read back by geojson.floorplan_from_geojson
    return out


def save_geojson(fp: Floorplan, path) -> Path:
    """Writes a floor plan atomically (a temporary file renamed into place)."""
    path = atomic_write(path, json.dumps(floorplan_to_geojson(fp), indent=1))
    return path
