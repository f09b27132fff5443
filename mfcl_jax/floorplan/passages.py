"""Where rooms meet without a door: open passages, and the walls of a plan of rooms only.

Many plans mark no door where rooms are joined by an opening (a ring corridor around a core,
a corridor opening into a lobby, the arms of a cross meeting a hub), and many indoor exports
hold rooms only (IfcSpace-only models, room-polygon GeoJSON). Two rules read them:

* two rooms whose boundaries run within ``TOUCH`` of each other along a stretch of at least
  ``PASSAGE`` (wide enough for a person) that no wall covers are joined by an open passage
  (``open_adjacency``): a wall gap between two rooms is a passage;
* a plan without walls gets the rooms' boundaries as walls, except where a boundary lies on
  another room's (within ``COINCIDE``: the two rooms share an edge, an opening with nothing
  in it; ``walls_from_rooms``). Rooms that face each other across a gap (a wall's thickness,
  up to ``TOUCH``) keep both boundaries as walls: the wall between them is in the building.
  Such a plan marks no door, so rooms that face each other across a wall along at least
  ``PASSAGE`` may be joined anywhere on it (``Floorplan.adjacency`` reads them with
  ``open_adjacency`` and no walls); the gate then rules out only jumps between rooms that do
  not face each other and walks through the outer wall.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString, MultiLineString
from shapely.ops import unary_union

__all__ = [
    "TOUCH",
    "PASSAGE",
    "COINCIDE",
    "DERIVED_THICKNESS",
    "open_adjacency",
    "walls_from_rooms",
]

TOUCH = 0.45  # m: two rooms this close face each other across a wall or an opening
PASSAGE = 0.6  # m: the narrowest opening a person walks through
COINCIDE = 0.05  # m: two room boundaries this close are one shared edge (no wall between)
DERIVED_THICKNESS = 0.10  # m: walls drawn along a rooms-only plan's free boundaries


def _lines(geom) -> list[LineString]:
    if geom.is_empty:
        return []
    if isinstance(geom, LineString):
        return [geom]
    if isinstance(geom, MultiLineString):
        return list(geom.geoms)
    return [g for g in getattr(geom, "geoms", []) if isinstance(g, LineString)]


def open_adjacency(polygons, wall_solid, touch: float = TOUCH, passage: float = PASSAGE):
    """``(R, R)`` bool: pairs of rooms joined by an open passage (diagonal False).

    Args:
        polygons: the rooms' shapely polygons.
        wall_solid: the union of the wall footprints (may be empty).
        touch, passage: see the module docstring (m).
    """
    n = len(polygons)
    adj = np.zeros((n, n), bool)
    if n < 2:
        return adj
    tree = shapely.STRtree(polygons)
    walls = wall_solid.buffer(0.05) if not wall_solid.is_empty else None
    for a, pa in enumerate(polygons):
        for b in tree.query(pa.buffer(touch)):
            b = int(b)
            if b <= a:
                continue
            facing = pa.boundary.intersection(polygons[b].buffer(touch))
            if walls is not None:
                facing = facing.difference(walls)
            # the longest uncovered stretch, not the sum of slivers between wall pieces
            if max((ln.length for ln in _lines(facing)), default=0.0) >= passage:
                adj[a, b] = adj[b, a] = True
    return adj


def walls_from_rooms(polygons, coincide: float = COINCIDE) -> np.ndarray:
    """Wall centre lines ``(W, 2, 2)`` of a plan of rooms only: every room's boundary, except
    where it lies within ``coincide`` of another room's (a shared edge: there the two rooms
    meet with nothing between them). Boundaries facing another room across a wall's gap are
    walls."""
    segs = []
    for a, pa in enumerate(polygons):
        others = [p for b, p in enumerate(polygons) if b != a and p.distance(pa) <= coincide]
        free = pa.boundary
        if others:
            free = free.difference(unary_union(others).buffer(coincide))
        for line in _lines(free):
            xy = np.asarray(line.coords)
            for p, q in zip(xy[:-1], xy[1:], strict=True):
                if np.hypot(*(q - p)) > 1e-6:
                    segs.append((p, q))
    return np.asarray(segs, np.float64).reshape(-1, 2, 2)
