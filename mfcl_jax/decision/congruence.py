"""Translational self-motions of a building: the offsets between congruent rooms.

Two rooms are congruent when their footprints overlap with IoU ``>= min_iou`` after their
centroids are aligned (room polygons for a ``Floorplan``, cell sets for bare ``Rasters``).
The offsets (both signs, near-duplicates merged) and their fundamentals (offsets that are not
integer multiples of a shorter one) generate the alias probe's periods; the lattice test
validates a period against them. The rotational part is in ``symmetry``.
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.floorplan.raster import Rasters

__all__ = ["translations"]


def _congruent_offsets(r: Rasters, min_iou: float) -> np.ndarray:
    """Centroid offsets ``b - a`` between rooms whose cell sets match after translation."""
    rid = np.asarray(r.room_id)
    h, w = rid.shape
    cells, cents = [], []
    for i in range(r.n_rooms):
        iy, ix = np.nonzero(rid == i)
        cells.append((iy, ix))
        cents.append(np.array([ix.mean(), iy.mean()]) if ix.size else np.array([np.nan] * 2))
    out = []
    for a in range(r.n_rooms):
        for b in range(a + 1, r.n_rooms):
            (ya, xa), (yb, xb) = cells[a], cells[b]
            if (
                xa.size == 0
                or xb.size == 0
                or min(xa.size, xb.size) < min_iou * max(xa.size, xb.size)
            ):
                continue
            sx, sy = np.round(cents[a] - cents[b]).astype(int)
            key_a = ya.astype(np.int64) * (4 * w) + xa
            key_b = (yb + sy).astype(np.int64) * (4 * w) + (xb + sx)
            inter = np.intersect1d(key_a, key_b, assume_unique=True).size
            if inter / (xa.size + xb.size - inter) >= min_iou:
                off = (cents[b] - cents[a]) * r.res
                out.extend([off, -off])
    return np.asarray(out, np.float64).reshape(-1, 2)


def _fundamentals(offsets: np.ndarray, tol: float) -> np.ndarray:
    """Offsets (one sign) that are not integer multiples of a shorter offset."""
    canon = [o if (o[0] > 1e-6 or (abs(o[0]) <= 1e-6 and o[1] > 0)) else -o for o in offsets]
    canon = sorted(canon, key=lambda o: float(np.hypot(*o)))
    keep: list[np.ndarray] = []
    for o in canon:
        redundant = False
        for f in keep:
            n = round(float(np.dot(o, f) / np.dot(f, f)))
            if n >= 1 and np.hypot(*(o - n * f)) <= tol:
                redundant = True
                break
        if not redundant:
            keep.append(o)
    return np.asarray(keep, np.float64).reshape(-1, 2)


def _congruent_offsets_poly(fp, min_iou: float) -> np.ndarray:
    """Centroid offsets ``b - a`` between rooms whose polygons match after translation (exact
    geometry, so an exact copy scores IoU 1 whatever its offset on the grid)."""
    from shapely import affinity

    polys = [room.polygon for room in fp.rooms]
    cents = [np.array([p.centroid.x, p.centroid.y]) for p in polys]
    out = []
    for a in range(len(polys)):
        for b in range(a + 1, len(polys)):
            pa, pb = polys[a], polys[b]
            if min(pa.area, pb.area) < min_iou * max(pa.area, pb.area):
                continue
            off = cents[b] - cents[a]
            moved = affinity.translate(pa, off[0], off[1])
            inter = moved.intersection(pb).area
            if inter / (pa.area + pb.area - inter) >= min_iou:
                out.extend([off, -off])
    return np.asarray(out, np.float64).reshape(-1, 2)


def translations(source, r, min_iou: float, dedupe: float, max_generators: int):
    """``(offsets (P, 2), generators (G, 2))`` of ``source`` (``Floorplan`` or ``Rasters``,
    ``r`` its host rasters): congruent-room offsets merged within ``dedupe`` m, and at most
    ``max_generators`` fundamentals."""
    if isinstance(source, Rasters):
        offs = _congruent_offsets(r, min_iou)
    else:
        offs = _congruent_offsets_poly(source, min_iou)
    uniq: list[np.ndarray] = []
    for o in offs:
        if all(np.hypot(*(o - u)) > dedupe for u in uniq):
            uniq.append(o)
    offs = np.asarray(uniq, np.float64).reshape(-1, 2)
    return offs, _fundamentals(offs, dedupe)[:max_generators]
