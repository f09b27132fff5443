"""Rotational self-motions of a building, found on the host from its room polygons.

A building whose rooms come in rotated pairs (two apartment units that are 180-degree images of
each other) aliases a trajectory onto the rotated copy of itself: ``g T*`` is as feasible as
``T*`` for every rigid motion ``g`` that maps the building onto itself. The translational part
of the symmetry group is the congruent-room offsets of ``gate``; this module finds the
rotational part.

For every ordered pair of distinct rooms ``(a, b)`` of similar area and every quarter turn
``theta`` in 90, 180, 270 degrees, room ``a`` is rotated by ``theta`` about its centroid and
moved onto ``b``'s centroid; when the polygons then overlap with IoU ``>= min_iou``, the pair
witnesses the rigid motion ``g = T(c_b) R(theta) T(-c_a)`` (a pose ``(x, y, theta)`` in
SE(2), acting on the floor-plan frame).

Pairs that are already congruent under a pure translation (IoU ``>= min_iou`` at 0 degrees)
give no rotational motion: their 180-degree match only says that each room is itself
point-symmetric (a rectangle), which is a self-rotation; the translational probe guards the
pair and a single symmetric room is left to the multimodal state. Self-pairs ``a == b`` are
skipped for the same reason.

Every room of a rotated unit witnesses the same ``g``, so motions are merged when they move the
building's centre to within ``dedupe`` m of each other with headings within ``angle_tol``. The
support of a motion (how many rooms it maps onto a congruent room) is reported for audits;
motions are ordered by support, most supported first.
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.se2 import wrap_host

__all__ = ["QUARTER_TURNS", "rotational_motions", "motion_support"]

QUARTER_TURNS = (90.0, 180.0, 270.0)


def _ious(pa, pb) -> np.ndarray:
    """Element-wise IoU of two arrays of polygons (shapely's vectorised operations)."""
    import shapely

    inter = shapely.area(shapely.intersection(pa, pb))
    return inter / np.maximum(shapely.area(pa) + shapely.area(pb) - inter, 1e-12)


def _moved(polys, g):
    """``polys`` (an array of polygons) under the rigid motion ``g = (x, y, theta)``."""
    import shapely

    c, s = np.cos(g[..., 2]), np.sin(g[..., 2])
    rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (..., 2, 2)
    coords, idx = shapely.get_coordinates(polys, return_index=True)
    rot, t = np.broadcast_to(rot, (len(polys), 2, 2)), np.broadcast_to(g[..., :2], (len(polys), 2))
    moved = np.einsum("nij,nj->ni", rot[idx], coords) + t[idx]
    return shapely.set_coordinates(shapely.transform(polys, lambda x: x), moved)


def _pair_motion(ca: np.ndarray, cb: np.ndarray, theta) -> np.ndarray:
    """``T(c_b) R(theta) T(-c_a)`` as ``(..., 3)`` (broadcast over pairs and turns)."""
    c, s = np.cos(theta), np.sin(theta)
    tx = cb[..., 0] - (c * ca[..., 0] - s * ca[..., 1])
    ty = cb[..., 1] - (s * ca[..., 0] + c * ca[..., 1])
    return np.stack([tx, ty, np.arctan2(s, c) + 0.0 * tx], -1)


def _similar(areas: np.ndarray, min_iou: float) -> np.ndarray:
    """``(N, N)``: pairs of distinct rooms whose areas could reach IoU ``min_iou``."""
    lo = np.minimum(areas[:, None], areas[None, :])
    hi = np.maximum(areas[:, None], areas[None, :])
    return (lo >= min_iou * hi) & ~np.eye(len(areas), dtype=bool)


def motion_support(polys, g: np.ndarray, min_iou: float) -> int:
    """Number of rooms that ``g`` maps onto a different room with IoU ``>= min_iou``."""
    import shapely

    polys = np.asarray(polys, dtype=object)
    if len(polys) == 0:
        return 0
    similar = _similar(shapely.area(polys), min_iou)
    moved = _moved(polys, np.asarray(g, np.float64))
    # only pairs whose boxes meet can overlap: the plan's tree finds them
    a, b = shapely.STRtree(polys).query(moved, predicate="intersects")
    keep = similar[a, b]
    a, b = a[keep], b[keep]
    hit = _ious(moved[a], polys[b]) >= min_iou
    return int(np.unique(a[hit]).size)


def rotational_motions(
    fp, min_iou: float, dedupe: float = 0.5, angle_tol: float = float(np.deg2rad(5.0))
) -> tuple[np.ndarray, np.ndarray]:
    """Rigid motions by a quarter turn that map rooms onto distinct congruent rooms.

    Args:
        fp: a ``Floorplan`` (its room polygons are read).
        min_iou: IoU after alignment above which two rooms are congruent.
        dedupe: motions moving the building centre to within this distance (m) are merged.
        angle_tol: and whose headings differ by at most this (rad).

    Returns:
        ``(motions (M, 3), support (M,))``: motions ``(x, y, theta)`` in the floor-plan frame,
        most supported first, and how many rooms each maps onto a congruent room.
    """
    import shapely

    polys = np.asarray([room.polygon for room in fp.rooms] + [None], dtype=object)[:-1]
    if len(polys) == 0:
        return np.zeros((0, 3)), np.zeros((0,), np.int64)
    cents = shapely.get_coordinates(shapely.centroid(polys))
    bounds = shapely.bounds(polys)
    centre = (bounds[:, :2].min(0) + bounds[:, 2:].max(0)) / 2
    a, b = np.nonzero(_similar(shapely.area(polys), min_iou))
    # a translated copy is the translational probe's business, not a rotation
    shift = np.concatenate([cents[b] - cents[a], np.zeros((len(a), 1))], 1)
    translated = _ious(_moved(polys[a], shift), polys[b]) >= min_iou
    a, b = a[~translated], b[~translated]
    turns = np.deg2rad(np.asarray(QUARTER_TURNS))
    g = _pair_motion(cents[a][:, None], cents[b][:, None], turns[None, :])  # (P, 3, 3)
    pa = np.repeat(polys[a], len(turns))
    hit = _ious(_moved(pa, g.reshape(-1, 3)), np.repeat(polys[b], len(turns))) >= min_iou
    found = g.reshape(-1, 3)[hit]
    uniq: list[np.ndarray] = []
    for gi in found:
        at = _apply(gi, centre)
        if all(
            np.hypot(*(at - _apply(u, centre))) > dedupe or abs(wrap_host(gi[2] - u[2])) > angle_tol
            for u in uniq
        ):
            uniq.append(gi)
    support = np.array([motion_support(polys, gi, min_iou) for gi in uniq], np.int64)
    order = np.argsort(-support, kind="stable")
    return np.asarray(uniq, np.float64).reshape(-1, 3)[order], support[order]


def _apply(g: np.ndarray, p: np.ndarray) -> np.ndarray:
    c, s = np.cos(g[2]), np.sin(g[2])
    return np.array([c * p[0] - s * p[1] + g[0], s * p[0] + c * p[1] + g[1]])
