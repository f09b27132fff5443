"""IFC floor plans: a horizontal cut through the building model at one storey.

The plan is what a LiDAR at about hip height sees: every wall solid (``IfcWall`` and its
subtypes, ``IfcCurtainWall``, ``IfcColumn``) and every ``IfcSpace`` solid is triangulated in
world coordinates by ifcopenshell and cut with the plane ``z = storey elevation + cut_height``
(``ifc_section``). Door openings in the walls show up as gaps because the wall solids already
have them subtracted. Rooms, doors and open passages are read off the cut (``ifc_rooms``).

Lengths are converted to metres with the file's length unit.
"""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path

import numpy as np
from shapely.geometry import Polygon

from mfcl_jax.floorplan.ifc_rooms import rooms_and_doors
from mfcl_jax.floorplan.ifc_section import polygon_parts, section_mesh
from mfcl_jax.floorplan.model import Floorplan, FloorplanError

__all__ = ["load_ifc", "ifc_storeys", "section_mesh"]

WALL_TYPES = ("IfcWall", "IfcCurtainWall", "IfcColumn")  # IfcWall covers IfcWallStandardCase
# Windows close the wall line in the plan (a cut at 1 m often passes through them).
WINDOW_TYPES = ("IfcWindow",)
# Section polygons smaller than this (m^2) are mesh slivers, not walls.
MIN_WALL_AREA = 1e-3
MIN_ROOM_AREA = 0.05

_CACHE: dict = {}


# ---------------------------------------------------------------------- file access
def _check_complete(path: Path) -> None:
    """An IFC text file (STEP, ISO 10303-21) ends with ``END-ISO-10303-21;``: one that does
    not was cut short (an export or a copy interrupted), and what it holds is not the model."""
    with path.open("rb") as f:
        head = f.read(64)
        if not head.lstrip().startswith(b"ISO-10303-21;"):
            return  # not a STEP text file: ifcopenshell says what it is
        f.seek(0, 2)
        size = f.tell()
        f.seek(max(size - 4096, 0))
        tail = f.read()
    if b"END-ISO-10303-21;" not in tail:
        raise FloorplanError(
            f"{path}: the IFC file is truncated: it does not end with END-ISO-10303-21; "
            f"({size} bytes; the export or the copy was cut short); export the model again"
        )


def _open(path: Path):
    import ifcopenshell

    if not path.is_file():
        raise FloorplanError(f"{path}: file not found")
    _check_complete(path)
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
        polys = polygon_parts(section_mesh(verts, faces, zc))
        if el.is_a("IfcSpace"):
            polys = [p for p in polys if p.area >= MIN_ROOM_AREA]
            if polys:
                space_sections.append((el, polys))
        else:
            wall_polys.extend(p.simplify(0.002) for p in polys if p.area >= MIN_WALL_AREA)
    wall_polys = [p for w in wall_polys for p in polygon_parts(w)]
    if not wall_polys:
        raise FloorplanError(f"{path}: {where}: no wall crosses the cut plane")
    if not space_sections:
        raise FloorplanError(f"{path}: {where}: no IfcSpace crosses the cut plane")

    rooms, doors = rooms_and_doors(space_sections, door_meshes, wall_polys)
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
