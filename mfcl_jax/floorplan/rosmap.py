"""ROS map_server occupancy maps as floor plans.

A map is a YAML file (``image, resolution, origin, negate, occupied_thresh, free_thresh``) and
a greyscale image. Cells are classified the map_server way: ``p = (255 - v) / 255`` (or
``v / 255`` when ``negate``), occupied if ``p > occupied_thresh``, free if ``p < free_thresh``,
unknown otherwise. Image row 0 is the top of the map; ``origin`` is the world pose of the
lower-left pixel corner (its yaw, when non-zero, rotates the whole plan).

Walls: connected occupied regions, vectorised cell-exactly and simplified to ``res / 2``.
Rooms: ``roomseg.segment_rooms`` (rooms and corridor segments, split at doorways and
junctions), each vectorised cell-exactly (wall or unknown pockets under 1 m^2 inside it
filled), so every labelled free cell's centre lies in exactly its room's polygon. Doors: one
per pair of rooms that share a boundary, a segment along the longest contiguous piece of it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import shapely
import shapely.affinity
from scipy import ndimage
from shapely.geometry import Polygon

from mfcl_jax.floorplan.model import Door, Floorplan, FloorplanError, Room
from mfcl_jax.floorplan.roomseg import segment_rooms
from mfcl_jax.floorplan.rosmap_grid import read_rosmap_grid

__all__ = ["load_rosmap", "read_rosmap_grid"]


# ---------------------------------------------------------------------- vectorising
def _cells_to_polygons(mask: np.ndarray, res: float) -> list[Polygon]:
    """Exact polygon(s) of a cell mask (grid coordinates scaled by ``res``), via row runs."""
    edge = np.diff(np.pad(mask.astype(np.int8), ((0, 0), (1, 1))), axis=1)
    rows, start = np.nonzero(edge == 1)
    _, end = np.nonzero(edge == -1)  # row-major order: the runs pair up
    if not rows.size:
        return []
    boxes = shapely.box(start * res, rows * res, end * res, (rows + 1) * res)
    geom = shapely.simplify(shapely.union_all(boxes), 0.0)  # drops collinear vertices only
    return [g for g in shapely.get_parts(geom) if isinstance(g, Polygon)]


def _simplified(poly: Polygon, tol: float) -> list[Polygon]:
    poly = poly.simplify(tol)
    if not poly.is_valid:
        poly = shapely.make_valid(poly)
    return [g for g in shapely.get_parts(poly) if isinstance(g, Polygon) and g.area > 0]


def _room_polygon(lab: np.ndarray, r: int, res: float, min_hole: float) -> Polygon:
    """Cell-exact polygon of room ``r`` (4-connected), with small pockets of non-free cells
    filled (pockets holding another room's cells stay holes)."""
    rows, cols = np.nonzero(lab == r)
    sl = (slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1))
    mask = lab[sl] == r
    holes, n = ndimage.label(ndimage.binary_fill_holes(mask) & ~mask)
    if n:
        size = ndimage.sum_labels(np.ones_like(holes), holes, np.arange(1, n + 1)) * res * res
        other = ndimage.maximum(lab[sl] >= 0, holes, np.arange(1, n + 1)).astype(bool)
        fill = np.concatenate([[False], (size < min_hole) & ~other])
        mask |= fill[holes]
    (poly,) = _cells_to_polygons(mask, res)
    return shapely.affinity.translate(poly, sl[1].start * res, sl[0].start * res)


def load_rosmap(
    yaml_path, free_thresh: float | None = None, occupied_thresh=None, **segmentation
) -> Floorplan:
    """Loads a ROS map_server map (YAML + PGM/PNG) as a floor plan.

    Args:
        yaml_path: the map's YAML file.
        free_thresh: overrides the YAML's ``free_thresh`` (explicitly, never silently).
        occupied_thresh: overrides the YAML's ``occupied_thresh``.
        **segmentation: overrides for ``roomseg.segment_rooms`` parameters.

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
            for q in _simplified(p, res / 2):
                walls.append(shapely.affinity.translate(q, *off))
    segmentation.setdefault("occ", occ)
    lab = segment_rooms(free, res, **segmentation)
    n_rooms = int(lab.max()) + 1
    if n_rooms == 0:
        raise FloorplanError(f"{path}: the free space has no room wider than a corridor core")
    rooms = [Room(f"r{r:02d}", _room_polygon(lab, r, res, 1.0)) for r in range(n_rooms)]
    doors = _doors_from_labels(lab, res, rooms)
    c, s = math.cos(yaw), math.sin(yaw)
    rot_t = np.array([[c, s], [-s, c]])  # row vectors: q @ rot_t rotates by yaw

    def to_world(g):
        return shapely.transform(g, lambda q: q @ rot_t + [ox, oy])

    return Floorplan(
        walls=np.zeros((0, 2, 2)),
        thickness=np.zeros((0,)),
        rooms=tuple(Room(r.name, to_world(r.polygon)) for r in rooms),
        doors=tuple(Door(d.segment @ rot_t + [ox, oy], d.rooms) for d in doors),
        wall_polygons=tuple(to_world(w) for w in walls),
        name=path.stem,
        source=str(path),
        outside_unknown=True,  # unknown cells: never observed, not known to be outdoors
    )


def _doors_from_labels(lab, res, rooms) -> list[Door]:
    """One door per adjacent room pair: a segment along their longest contiguous boundary."""
    keys, pts = [], []
    for axis in (0, 1):
        a = lab[:, :-1] if axis == 1 else lab[:-1, :]
        b = lab[:, 1:] if axis == 1 else lab[1:, :]
        m = (a >= 0) & (b >= 0) & (a != b)
        rr, cc = np.nonzero(m)
        keys.append(np.stack([np.minimum(a[m], b[m]), np.maximum(a[m], b[m])], 1))
        # Shared cell edge midpoints in half cells: (2 col + 2, 2 row + 1) or (2 col + 1, ...).
        pts.append(np.stack([2 * cc + 1 + axis, 2 * rr + 2 - axis], 1))
    keys, pts = np.concatenate(keys), np.concatenate(pts)
    order = np.lexsort((keys[:, 1], keys[:, 0]))
    keys, pts = keys[order], pts[order]
    cuts = np.flatnonzero(np.any(np.diff(keys, axis=0) != 0, axis=1)) + 1
    doors = []
    for k, p in zip(np.split(keys, cuts), np.split(pts, cuts), strict=True):
        if not len(k):
            continue
        lo = p.min(0)
        img = np.zeros(tuple(p.max(0) - lo + 1), bool)
        img[tuple((p - lo).T)] = True
        # Edges of one boundary piece are at most 2 half cells apart.
        pieces, _ = ndimage.label(ndimage.binary_dilation(img), structure=np.ones((3, 3)))
        ids = pieces[tuple((p - lo).T)]
        q = p[ids == np.bincount(ids).argmax()] * (res / 2)
        c = q.mean(0)
        u = np.linalg.svd(q - c, full_matrices=False)[2][0] if len(q) > 1 else np.array([1.0, 0])
        proj = (q - c) @ u
        half = max((proj.max() - proj.min()) / 2, res / 2)
        mid = c + u * (proj.max() + proj.min()) / 2
        i, j = int(k[0, 0]), int(k[0, 1])
        seg = np.stack([mid - u * half, mid + u * half])
        doors.append(Door(seg, (rooms[i].name, rooms[j].name)))
    return doors
