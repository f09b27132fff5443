"""ROS map_server occupancy maps as floor plans, with a room segmentation of the free space.

A map is a YAML file (``image, resolution, origin, negate, occupied_thresh, free_thresh``) and
a greyscale image. Cells are classified the map_server way: ``p = (255 - v) / 255`` (or
``v / 255`` when ``negate``), occupied if ``p > occupied_thresh``, free if ``p < free_thresh``,
unknown otherwise. Image row 0 is the top of the map; ``origin`` is the world pose of the
lower-left pixel corner (its yaw, when non-zero, rotates the whole plan).

Walls: connected occupied regions, vectorised cell-exactly and simplified to ``res / 2``.

Rooms (a distance-transform segmentation, in the spirit of the morphological segmentations of
Bormann et al. 2016, written from that description):
1. ``D`` = distance (m) from every free cell to the nearest non-free cell.
2. Room cores are the connected components of ``D > core_clearance``: a door of width ``w``
   has clearance at most ``w / 2``, so doors narrower than ``2 * core_clearance`` cut the free
   space into cores while rooms and corridors keep theirs. Cores under ``min_core_area`` are
   dropped (clutter pockets).
3. The cores grow back over the free space one cell ring at a time (a geodesic Voronoi
   partition), so each free cell joins the core it reaches first through free space.
4. Neighbouring regions whose shared boundary is longer than ``max_door_width`` are the same
   room split by clutter and are merged; regions under ``min_room_area`` join the neighbour
   they share most boundary with.
5. Every remaining shared boundary is a door: a segment across the passage between the two
   rooms, so the room graph comes from the map alone.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import shapely
import shapely.affinity
from scipy import ndimage
from shapely.geometry import Polygon, box
from shapely.ops import unary_union

from mfcl_jax.floorplan.model import Door, Floorplan, FloorplanError, Room
from mfcl_jax.floorplan.rosmap_grid import read_rosmap_grid

__all__ = ["load_rosmap", "read_rosmap_grid", "segment_rooms"]


# ---------------------------------------------------------------------- segmentation
def segment_rooms(
    free: np.ndarray,
    res: float,
    core_clearance: float = 0.6,
    min_core_area: float = 1.0,
    max_door_width: float = 1.6,
    min_room_area: float = 3.0,
    seal: float = 0.5,
    occ: np.ndarray | None = None,
) -> np.ndarray:
    """Partitions the free cells into rooms.

    Args:
        free: ``(H, W)`` bool free space.
        res: cell size (m).
        core_clearance: clearance (m) a cell needs to seed a room core.
        min_core_area: smallest core kept (m^2).
        max_door_width: longer shared boundaries (m) merge two regions into one room.
        min_room_area: smaller regions (m^2) join their main neighbour.
        seal: wall gaps up to ``2 * seal`` (m) count as closed when telling the building's
            inside from the free space around it.
        occ: ``(H, W)`` bool occupied cells; when given, free space connected to the map
            border through the sealed walls is outside the building and gets no room.

    Returns:
        ``(H, W)`` int32 room labels ``0..R-1``, -1 outside the free space.
    """
    if occ is not None and seal > 0:
        free = free & ~_outside(free, occ, res, seal)
    dist = ndimage.distance_transform_edt(free) * res
    cores, n = ndimage.label(dist > core_clearance)
    if n:
        sizes = ndimage.sum_labels(np.ones_like(cores), cores, np.arange(1, n + 1)) * res * res
        keep = np.concatenate([[0], np.where(sizes >= min_core_area, np.arange(1, n + 1), 0)])
        cores = keep[cores]
    lab = cores.astype(np.int32)
    # Geodesic growth: one ring of cells per step, only through free space.
    todo = free & (lab == 0)
    while todo.any():
        grown = ndimage.grey_dilation(lab, size=(3, 3))
        new = todo & (grown > 0)
        if not new.any():
            break
        lab[new] = grown[new]
        todo &= ~new
    lab = _merge_regions(lab, res, max_door_width, min_room_area)
    _, inv = np.unique(lab, return_inverse=True)
    out = inv.reshape(lab.shape).astype(np.int32) - (1 if (lab == 0).any() else 0)
    out[lab == 0] = -1
    return out


def _outside(free, occ, res, seal) -> np.ndarray:
    """Free cells reachable from the map border without passing within ``seal`` of a wall."""
    k = max(1, int(round(seal / res)))
    disk = np.hypot(*np.mgrid[-k : k + 1, -k : k + 1]) <= k
    open_space = free & ~ndimage.binary_dilation(occ, structure=disk)
    lab, _ = ndimage.label(open_space)
    border = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
    out = np.isin(lab, border[border > 0])
    # Give the sealed band on the outer side of the walls back to the outside.
    return ndimage.binary_dilation(out, iterations=k, mask=free)


def _boundaries(lab: np.ndarray) -> dict[tuple[int, int], int]:
    """Number of 4-neighbour cell pairs between each pair of labels (> 0)."""
    pairs: dict[tuple[int, int], int] = {}
    for a, b in ((lab[:, :-1], lab[:, 1:]), (lab[:-1, :], lab[1:, :])):
        m = (a > 0) & (b > 0) & (a != b)
        if not m.any():
            continue
        lo, hi = np.minimum(a[m], b[m]), np.maximum(a[m], b[m])
        keys, counts = np.unique(np.stack([lo, hi], 1), axis=0, return_counts=True)
        for (i, j), c in zip(keys.tolist(), counts.tolist(), strict=True):
            pairs[(i, j)] = pairs.get((i, j), 0) + c
    return pairs


def _merge_regions(lab, res, max_door_width, min_room_area):
    while True:
        pairs = _boundaries(lab)
        ids = np.unique(lab[lab > 0])
        sizes = ndimage.sum_labels(np.ones_like(lab), lab, ids) * res * res
        area = dict(zip(ids.tolist(), sizes.tolist(), strict=True))
        target = None
        wide = [(c, k) for k, c in pairs.items() if c * res > max_door_width]
        if wide:
            _, (i, j) = max(wide)
            target = (j, i)
        else:
            small = sorted((area[i], i) for i in ids.tolist() if area[i] < min_room_area)
            for _, i in small:
                nb = [(c, j if k == i else k) for (k, j), c in pairs.items() if i in (k, j)]
                if nb:
                    target = (i, max(nb)[1])
                    break
        if target is None:
            return lab
        lab[lab == target[0]] = target[1]


# ---------------------------------------------------------------------- vectorising
def _cells_to_polygons(mask: np.ndarray, res: float) -> list[Polygon]:
    """Exact polygon(s) of a cell mask (grid coordinates scaled by ``res``), via row runs."""
    boxes = []
    for r in np.flatnonzero(mask.any(1)):
        row = np.concatenate([[0], mask[r].astype(np.int8), [0]])
        d = np.diff(row)
        for s, e in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True):
            boxes.append(box(s * res, r * res, e * res, (r + 1) * res))
    if not boxes:
        return []
    geom = unary_union(boxes)
    return [g for g in shapely.get_parts(geom) if isinstance(g, Polygon)]


def _clean(poly: Polygon, tol: float, min_hole: float) -> list[Polygon]:
    holes = [h for h in poly.interiors if Polygon(h).area >= min_hole]
    poly = Polygon(poly.exterior, holes).simplify(tol)
    if not poly.is_valid:
        poly = shapely.make_valid(poly)
    return [g for g in shapely.get_parts(poly) if isinstance(g, Polygon) and g.area > 0]


def load_rosmap(
    yaml_path, free_thresh: float | None = None, occupied_thresh=None, **segmentation
) -> Floorplan:
    """Loads a ROS map_server map (YAML + PGM/PNG) as a floor plan.

    Args:
        yaml_path: the map's YAML file.
        free_thresh: overrides the YAML's ``free_thresh`` (explicitly, never silently).
        occupied_thresh: overrides the YAML's ``occupied_thresh``.
        **segmentation: overrides for ``segment_rooms`` parameters.

    Returns:
        A ``Floorplan`` with ``wall_polygons`` from the occupied cells, rooms ``r00``, ``r01``,
        ... from the segmentation of the free space, and one door per pair of rooms that share
        a boundary.

    Raises:
        FloorplanError: missing file or image, a bad YAML field (named with its value), or a
            map without occupied or free cells.
    """
    path = Path(yaml_path)
    occ, free, res, (ox, oy, yaw) = read_rosmap_grid(path, free_thresh, occupied_thresh)
    if not occ.any():
        raise FloorplanError(f"{path}: the map has no occupied cells (no walls)")
    if not free.any():
        raise FloorplanError(f"{path}: the map has no free cells (no rooms)")
    comps, n = ndimage.label(occ, structure=np.ones((3, 3)))
    walls = []
    for sl, i in zip(ndimage.find_objects(comps), range(1, n + 1), strict=True):
        sub = comps[sl] == i
        if sub.sum() < 3:  # isolated speckle, not structure
            continue
        off = (sl[1].start * res, sl[0].start * res)
        for p in _cells_to_polygons(sub, res):
            for q in _clean(p, res / 2, 0.0):
                walls.append(shapely.affinity.translate(q, *off))
    segmentation.setdefault("occ", occ)
    lab = segment_rooms(free, res, **segmentation)
    n_rooms = int(lab.max()) + 1
    if n_rooms == 0:
        raise FloorplanError(f"{path}: the free space has no room wider than a corridor core")
    rooms = []
    for r in range(n_rooms):
        polys = _cells_to_polygons(lab == r, res)
        poly = max(polys, key=lambda p: p.area)
        rooms.append(Room(f"r{r:02d}", max(_clean(poly, res / 2, 1.0), key=lambda p: p.area)))
    doors = _doors_from_labels(lab, res, rooms)

    def to_world(g):
        import shapely.affinity as aff

        g = aff.rotate(g, yaw, origin=(0, 0), use_radians=True)
        return aff.translate(g, ox, oy)

    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    return Floorplan(
        walls=np.zeros((0, 2, 2)),
        thickness=np.zeros((0,)),
        rooms=tuple(Room(r.name, to_world(r.polygon)) for r in rooms),
        doors=tuple(Door(d.segment @ rot.T + [ox, oy], d.rooms) for d in doors),
        wall_polygons=tuple(to_world(w) for w in walls),
        name=path.stem,
        source=str(path),
    )


def _doors_from_labels(lab, res, rooms) -> list[Door]:
    """One door per adjacent room pair: a segment along their shared cell boundary."""
    pts: dict[tuple[int, int], list] = {}
    h, w = lab.shape
    for axis in (0, 1):
        a = lab[:, :-1] if axis == 1 else lab[:-1, :]
        b = lab[:, 1:] if axis == 1 else lab[1:, :]
        m = (a >= 0) & (b >= 0) & (a != b)
        rr, cc = np.nonzero(m)
        # Midpoint of the shared cell edge, in metres.
        x = (cc + (1.0 if axis == 1 else 0.5)) * res
        y = (rr + (1.0 if axis == 0 else 0.5)) * res
        for i, j, px, py in zip(a[m], b[m], x, y, strict=True):
            pts.setdefault((min(i, j), max(i, j)), []).append((px, py))
    doors = []
    for (i, j), p in sorted(pts.items()):
        p = np.asarray(p)
        c = p.mean(0)
        if len(p) > 1:
            u = np.linalg.svd(p - c, full_matrices=False)[2][0]
        else:
            u = np.array([1.0, 0.0])
        proj = (p - c) @ u
        half = max((proj.max() - proj.min()) / 2, res / 2)
        seg = np.stack([c - u * half, c + u * half])
        doors.append(Door(seg, (rooms[i].name, rooms[j].name)))
    return doors
