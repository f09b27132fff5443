"""Rooms and doors of an IFC storey cut: spaces, door leaves and open passages.

Every ``IfcSpace`` cut becomes a named room. Doors (``IfcDoor``) crossing the plane become
``Door`` segments along their width; the rooms they join are the spaces found a short step
away on either side of the door leaf. Two spaces that meet without a wall between them are
joined by an open passage.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString
from shapely.ops import unary_union

from mfcl_jax.floorplan.ifc_section import polygon_parts
from mfcl_jax.floorplan.model import Door, Room

__all__ = ["rooms_and_doors"]

# Open passages (no IfcDoor) between spaces: reach (m) of each room into the gap and the
# narrowest opening (m) that counts as a passage.
PASSAGE_REACH = 0.35
PASSAGE_MIN_WIDTH = 0.6
# A door joins the space found within this distance (m) of its centre on each side.
DOOR_PROBE = (0.15, 0.3, 0.45)


def rooms_and_doors(space_sections, door_meshes, wall_polys) -> tuple[list[Room], list[Door]]:
    """The rooms of the cut spaces and the doors and open passages that join them.

    Args:
        space_sections: ``[(IfcSpace, [Polygon])]``, each space's pieces in the cut.
        door_meshes: ``[(IfcDoor, verts (V, 3))]`` of the doors that cross the cut plane.
        wall_polys: the wall footprints in the cut.

    Returns:
        ``(rooms, doors)``.
    """
    rooms = _rooms(space_sections)
    doors = _doors(door_meshes, rooms)
    doors += _passages(rooms, wall_polys, {frozenset(d.rooms) for d in doors})
    return rooms, doors


def _rooms(space_sections) -> list[Room]:
    rooms, used = [], set()
    for el, polys in space_sections:
        # Rooms are single polygons; a space cut into pieces keeps its largest piece.
        poly = max(polys, key=lambda p: p.area)
        poly = shapely.make_valid(poly.simplify(0.002))
        poly = max(polygon_parts(poly), key=lambda p: p.area)
        parts = [str(v).strip() for v in (el.Name, getattr(el, "LongName", None)) if v]
        base = " ".join(dict.fromkeys(parts)) or f"space#{el.id()}"
        name, k = base, 2
        while name in used:
            name, k = f"{base} ({k})", k + 1
        used.add(name)
        rooms.append(Room(name, poly))
    return rooms


def _doors(door_meshes, rooms: list[Room]) -> list[Door]:
    """Door segments along the leaf's width, joined to the spaces on either side."""
    doors = []
    polys = [r.polygon for r in rooms]
    tree = shapely.STRtree(polys)
    for el, verts in door_meshes:
        xy = verts[:, :2]
        c0 = xy.mean(0)
        u = _placement_x(el)
        if u is None:
            # No usable placement: the width axis is the dominant horizontal direction.
            _, v = np.linalg.eigh(np.cov((xy - c0).T) + 1e-12 * np.eye(2))
            u = v[:, 1]
        n = np.array([-u[1], u[0]])
        su, sn = (xy - c0) @ u, (xy - c0) @ n
        c = c0 + u * (su.max() + su.min()) / 2 + n * (sn.max() + sn.min()) / 2
        half = (su.max() - su.min()) / 2
        width = getattr(el, "OverallWidth", None)
        if width:
            half = min(half, float(width) * _scale_of(el) / 2)
        seg = np.stack([c - u * half, c + u * half])
        found = []
        for sign in (1.0, -1.0):
            for step in DOOR_PROBE:
                p = shapely.points(c + sign * n * step)
                hits = [int(i) for i in tree.query(p, predicate="within")]
                hits = [i for i in hits if i not in found]
                if hits:
                    found.append(hits[0])
                    break
        if not found:
            continue
        seg_line = LineString(seg)
        names = tuple(rooms[i].name for i in found if polys[i].distance(seg_line) <= 0.45)
        if names:
            doors.append(Door(seg, names))
    return doors


def _passages(rooms: list[Room], wall_polys, joined: set) -> list[Door]:
    """Open connections: two spaces that meet without a wall between them.

    The gap region is where both rooms, grown by ``PASSAGE_REACH``, overlap outside every
    wall; a part of it that touches both rooms and is at least ``PASSAGE_MIN_WIDTH`` wide
    is an opening. Its door segment lies along the first room's boundary inside the gap.
    """
    walls = unary_union(wall_polys).buffer(0.02)
    polys = [r.polygon for r in rooms]
    grown = [p.buffer(PASSAGE_REACH) for p in polys]
    tree = shapely.STRtree(grown)
    out = []
    for i, a in enumerate(polys):
        for j in sorted(int(k) for k in tree.query(grown[i])):
            if j <= i or frozenset((rooms[i].name, rooms[j].name)) in joined:
                continue
            b = polys[j]
            gap = grown[i].intersection(grown[j]).difference(walls)
            parts = [q for q in polygon_parts(gap) if q.distance(a) < 0.02 and q.distance(b) < 0.02]
            if not parts:
                continue
            part = max(parts, key=lambda q: q.area)
            edge = a.boundary.intersection(part)
            if edge.is_empty or edge.length < PASSAGE_MIN_WIDTH:
                continue
            pts = np.asarray(shapely.get_coordinates(edge))
            u = np.linalg.svd(pts - pts.mean(0), full_matrices=False)[2][0]
            c = np.asarray(part.centroid.coords[0])
            proj = (pts - c) @ u
            if np.ptp(proj) < PASSAGE_MIN_WIDTH:
                continue
            seg = np.stack([c + u * proj.min(), c + u * proj.max()])
            line = LineString(seg)
            if a.distance(line) <= 0.45 and b.distance(line) <= 0.45:
                out.append(Door(seg, (rooms[i].name, rooms[j].name)))
    return out


def _placement_x(el):
    """The door's local x axis (its width direction by IFC convention) if horizontal."""
    import ifcopenshell.util.placement as placement

    if el.ObjectPlacement is None:
        return None
    try:
        m = placement.get_local_placement(el.ObjectPlacement)
    except Exception:  # exotic placements (grid placements): fall back to the geometry
        return None
    x = np.asarray(m[:3, 0], float)
    h = np.linalg.norm(x[:2])
    if h < 0.9 * np.linalg.norm(x):
        return None
    return x[:2] / h


def _scale_of(el) -> float:
    import ifcopenshell.util.unit as unit

    return unit.calculate_unit_scale(el.file)
