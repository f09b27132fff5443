"""IFC floor plans: a horizontal cut through the building model at one storey.

The plan is what a LiDAR at about hip height sees: every wall solid (``IfcWall`` and its
subtypes, ``IfcCurtainWall``, ``IfcColumn``) and every ``IfcSpace`` solid is triangulated in
world coordinates by ifcopenshell and cut with the plane ``z = storey elevation + cut_height``.
A cut is exact for a closed triangle mesh: each triangle that straddles the plane contributes
one segment, the segments close into loops, and the loops are polygonised with the even-odd
rule (a face is solid if a ray from it crosses an odd number of section segments). Door
openings in the walls show up as gaps because the wall solids already have them subtracted.

Doors (``IfcDoor``) crossing the plane become ``Door`` segments along their width; the rooms
they join are the spaces found a short step away on either side of the door leaf.

Lengths are converted to metres with the file's length unit.
"""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from mfcl_jax.floorplan.model import Door, Floorplan, FloorplanError, Room

__all__ = ["load_ifc", "ifc_storeys", "section_mesh"]

WALL_TYPES = ("IfcWall", "IfcCurtainWall", "IfcColumn")  # IfcWall covers IfcWallStandardCase
# Windows close the wall line in the plan (a cut at 1 m often passes through them).
WINDOW_TYPES = ("IfcWindow",)
# Open passages (no IfcDoor) between spaces: reach (m) of each room into the gap and the
# narrowest opening (m) that counts as a passage.
PASSAGE_REACH = 0.35
PASSAGE_MIN_WIDTH = 0.6
# A door joins the space found within this distance (m) of its centre on each side.
DOOR_PROBE = (0.15, 0.3, 0.45)
# Section polygons smaller than this (m^2) are mesh slivers, not walls.
MIN_WALL_AREA = 1e-3
MIN_ROOM_AREA = 0.05

_CACHE: dict = {}


# ---------------------------------------------------------------------- mesh section
def section_mesh(verts: np.ndarray, faces: np.ndarray, z: float):
    """Cuts a triangle mesh with the plane ``z``.

    Args:
        verts: ``(V, 3)`` vertex positions.
        faces: ``(F, 3)`` vertex indices.
        z: height of the cutting plane.

    Returns:
        The section as a shapely (Multi)Polygon, or ``None`` when the mesh does not cross the
        plane. Open meshes whose loops do not close fall back to a thin buffer of the segments.
    """
    verts = np.asarray(verts, float).reshape(-1, 3)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    d = verts[:, 2] - z
    # A vertex on the plane counts as above it; this removes every degenerate case.
    above = d >= 0.0
    d = np.where(above & (d < 1e-9), 1e-9, d)
    fa = above[faces]
    cut = fa.any(1) & ~fa.all(1)
    if not cut.any():
        return None
    f = faces[cut]
    fa = fa[cut]
    pts = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        i, j = f[:, a], f[:, b]
        # Order each edge's vertices so a shared edge yields bit-identical points in both faces.
        lo, hi = np.minimum(i, j), np.maximum(i, j)
        with np.errstate(divide="ignore", invalid="ignore"):  # non-crossing edges: unused
            t = d[lo] / (d[lo] - d[hi])
            p = verts[lo, :2] + (verts[hi, :2] - verts[lo, :2]) * t[:, None]
        crosses = fa[:, a] != fa[:, b]
        pts.append((p, crosses))
    p = np.stack([q for q, _ in pts], 1)  # (F, 3, 2)
    c = np.stack([m for _, m in pts], 1)  # (F, 3): exactly two True per face
    segs = p[c].reshape(-1, 2, 2)
    segs = np.round(segs, 7)
    segs = segs[np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1) > 1e-7]
    if len(segs) == 0:
        return None
    lines = shapely.linestrings(segs)
    faces_poly = list(shapely.get_parts(shapely.polygonize(lines)))
    solid = [fp for fp in faces_poly if fp.area > 0 and _odd(fp.representative_point(), segs)]
    if solid:
        return unary_union(solid)
    # Not a closed mesh: a thin outline is still a usable wall footprint.
    return unary_union(shapely.buffer(lines, 0.01))


def _odd(pt, segs: np.ndarray) -> bool:
    """Even-odd rule: does a +x ray from ``pt`` cross an odd number of segments?"""
    x, y = pt.x, pt.y
    y0, y1 = segs[:, 0, 1], segs[:, 1, 1]
    straddle = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = segs[:, 0, 0] + (y - y0) * (segs[:, 1, 0] - segs[:, 0, 0]) / (y1 - y0)
    return bool(np.count_nonzero(straddle & (xc > x)) % 2)


def _polygons(geom) -> list[Polygon]:
    if geom is None or geom.is_empty:
        return []
    if not geom.is_valid:
        geom = shapely.make_valid(geom)
    return [g for g in shapely.get_parts(geom) if isinstance(g, Polygon) and not g.is_empty]


# ---------------------------------------------------------------------- file access
def _open(path: Path):
    import ifcopenshell

    if not path.is_file():
        raise FloorplanError(f"{path}: file not found")
    try:
        model = ifcopenshell.open(str(path))
    except Exception as e:  # ifcopenshell raises several unrelated types for a bad file
        raise FloorplanError(f"{path}: not a readable IFC file ({type(e).__name__}: {e})") from None
    if not model.by_type("IfcProject"):
        raise FloorplanError(f"{path}: IFC file has no IfcProject (empty or broken model)")
    return model


def _storey_list(model, scale: float) -> list[tuple[str, float, object]]:
    import ifcopenshell.util.placement as placement

    out = []
    for s in model.by_type("IfcBuildingStorey"):
        if s.ObjectPlacement is not None:
            elev = float(placement.get_local_placement(s.ObjectPlacement)[2, 3]) * scale
        else:
            elev = float(s.Elevation or 0.0) * scale
        out.append((str(s.Name or f"#{s.id()}"), elev, s))
    return sorted(out, key=lambda e: e[1])


def ifc_storeys(path) -> list[tuple[str, float]]:
    """The storeys of an IFC file as ``(name, elevation in m)``, lowest first."""
    import ifcopenshell.util.unit as unit

    model = _open(Path(path))
    return [(n, e) for n, e, _ in _storey_list(model, unit.calculate_unit_scale(model))]


def _describe(storeys) -> str:
    return ", ".join(f"{n!r} ({e:.2f} m)" for n, e, _ in storeys) or "none"


def _pick_storey(path, storeys, storey):
    import ifcopenshell.util.element as element

    if not storeys:
        raise FloorplanError(f"{path}: IFC file has no IfcBuildingStorey")
    if storey is None:
        for entry in storeys:
            dec = element.get_decomposition(entry[2])
            if any(e.is_a("IfcWall") for e in dec) and any(e.is_a("IfcSpace") for e in dec):
                return entry
        raise FloorplanError(
            f"{path}: no storey contains both walls and spaces; storeys: {_describe(storeys)}"
        )
    if isinstance(storey, str):
        for entry in storeys:
            if entry[0].strip().lower() == storey.strip().lower():
                return entry
        try:
            storey = float(storey)
        except ValueError:
            raise FloorplanError(
                f"{path}: unknown storey {storey!r}; available: {_describe(storeys)}"
            ) from None
    elev = float(storey)
    best = min(storeys, key=lambda e: abs(e[1] - elev))
    if abs(best[1] - elev) > 0.05:
        raise FloorplanError(
            f"{path}: no storey at elevation {elev:.2f} m; available: {_describe(storeys)}"
        )
    return best


def _meshes(model, elements):
    """Yields ``(element, verts (V, 3), faces (F, 3))`` in world coordinates (metres)."""
    import ifcopenshell.geom

    if not elements:
        return
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    it = ifcopenshell.geom.iterator(
        settings, model, max(1, min(8, multiprocessing.cpu_count())), include=elements
    )
    if not it.initialize():
        return
    # The iterator's threads finish shapes in any order: sorted by entity id, the rooms, doors
    # and walls (and the names and tours drawn from them) are the same in every run.
    out = []
    while True:
        shape = it.get()
        verts = np.asarray(shape.geometry.verts, float).reshape(-1, 3)
        faces = np.asarray(shape.geometry.faces, np.int64).reshape(-1, 3)
        out.append((int(shape.id), verts, faces))
        if not it.next():
            break
    for i, verts, faces in sorted(out, key=lambda x: x[0]):
        yield model.by_id(i), verts, faces


# ---------------------------------------------------------------------- the loader
def load_ifc(path, storey: str | float | None = None, cut_height: float = 1.0) -> Floorplan:
    """Loads one storey of an IFC model (IFC2X3 or IFC4) as a floor plan.

    Args:
        path: the ``.ifc`` file.
        storey: storey name (case-insensitive) or elevation in metres; default the lowest
            storey that contains both walls and spaces.
        cut_height: height (m) of the cutting plane above the storey elevation.

    Returns:
        A ``Floorplan`` with wall footprints as ``wall_polygons``, one room per ``IfcSpace``
        (named ``"<Name> <LongName>"``) and the doors crossing the cut.

    Raises:
        FloorplanError: unreadable file, unknown storey (the available ones are listed), or a
            storey whose cut meets no walls or no spaces.
    """
    import ifcopenshell.util.unit as unit

    path = Path(path)
    if not (np.isfinite(cut_height) and cut_height > 0):
        raise FloorplanError(f"{path}: cut_height={cut_height!r} must be a positive number")
    key = None
    if path.is_file():
        st = path.stat()
        key = (str(path.resolve()), st.st_mtime_ns, st.st_size, storey, float(cut_height))
        if key in _CACHE:
            return _CACHE[key]
    t0 = time.perf_counter()
    model = _open(path)
    scale = unit.calculate_unit_scale(model)
    storeys = _storey_list(model, scale)
    sname, elev, _ = _pick_storey(path, storeys, storey)
    zc = elev + float(cut_height)
    where = f"storey {sname!r} (cut at z={zc:.2f} m)"

    walls_el = [e for t in WALL_TYPES + WINDOW_TYPES for e in model.by_type(t)]
    spaces_el = list(model.by_type("IfcSpace"))
    doors_el = list(model.by_type("IfcDoor"))
    wall_polys: list[Polygon] = []
    space_sections: list[tuple[object, list[Polygon]]] = []
    door_meshes = []
    for el, verts, faces in _meshes(model, walls_el + spaces_el + doors_el):
        if len(verts) == 0 or not (verts[:, 2].min() < zc < verts[:, 2].max()):
            continue
        if el.is_a("IfcDoor"):
            door_meshes.append((el, verts))
            continue
        polys = _polygons(section_mesh(verts, faces, zc))
        if el.is_a("IfcSpace"):
            polys = [p for p in polys if p.area >= MIN_ROOM_AREA]
            if polys:
                space_sections.append((el, polys))
        else:
            wall_polys.extend(p.simplify(0.002) for p in polys if p.area >= MIN_WALL_AREA)
    wall_polys = [p for w in wall_polys for p in _polygons(w)]
    if not wall_polys:
        raise FloorplanError(f"{path}: {where}: no wall crosses the cut plane")
    if not space_sections:
        raise FloorplanError(f"{path}: {where}: no IfcSpace crosses the cut plane")

    rooms = _rooms(space_sections)
    doors = _doors(door_meshes, rooms)
    doors += _passages(rooms, wall_polys, {frozenset(d.rooms) for d in doors})
    fp = Floorplan(
        walls=np.zeros((0, 2, 2)),
        thickness=np.zeros((0,)),
        rooms=tuple(rooms),
        doors=tuple(doors),
        wall_polygons=tuple(wall_polys),
        name=f"{path.stem} {sname}",
        source=f"{path} [{sname}]",
    )
    fp._cache["load_seconds"] = time.perf_counter() - t0
    if key is not None:
        _CACHE[key] = fp
    return fp


def _rooms(space_sections) -> list[Room]:
    rooms, used = [], set()
    for el, polys in space_sections:
        # Rooms are single polygons; a space cut into pieces keeps its largest piece.
        poly = max(polys, key=lambda p: p.area)
        poly = shapely.make_valid(poly.simplify(0.002))
        poly = max(_polygons(poly), key=lambda p: p.area)
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
            parts = [q for q in _polygons(gap) if q.distance(a) < 0.02 and q.distance(b) < 0.02]
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
