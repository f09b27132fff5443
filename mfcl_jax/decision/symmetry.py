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

__all__ = ["QUARTER_TURNS", "rotational_motions", "motion_support"]

QUARTER_TURNS = (90.0, 180.0, 270.0)


def _iou(pa, pb) -> float:
    inter = pa.intersection(pb).area
    return float(inter / max(pa.area + pb.area - inter, 1e-12))


def _moved(poly, g):
    """``poly`` under the rigid motion ``g = (x, y, theta)``."""
    from shapely import affinity

    c, s = np.cos(g[2]), np.sin(g[2])
    return affinity.affine_transform(poly, [c, -s, s, c, g[0], g[1]])


def _pair_motion(ca: np.ndarray, cb: np.ndarray, theta: float) -> np.ndarray:
    """``T(c_b) R(theta) T(-c_a)`` as ``(x, y, theta)``."""
    c, s = np.cos(theta), np.sin(theta)
    t = cb - np.array([c * ca[0] - s * ca[1], s * ca[0] + c * ca[1]])
    return np.array([t[0], t[1], np.arctan2(s, c)])


def _similar_area(pa, pb, min_iou: float) -> bool:
    return min(pa.area, pb.area) >= min_iou * max(pa.area, pb.area)


def motion_support(polys, g: np.ndarray, min_iou: float) -> int:
    """Number of rooms that ``g`` maps onto a different room with IoU ``>= min_iou``."""
    n = 0
    for a, pa in enumerate(polys):
        moved = _moved(pa, g)
        if any(
            b != a and _similar_area(pa, pb, min_iou) and _iou(moved, pb) >= min_iou
            for b, pb in enumerate(polys)
        ):
            n += 1
    return n


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
    from shapely import affinity

    polys = [room.polygon for room in fp.rooms]
    if not polys:
        return np.zeros((0, 3)), np.zeros((0,), np.int64)
    cents = [np.array([p.centroid.x, p.centroid.y]) for p in polys]
    lo = np.min([p.bounds[:2] for p in polys], axis=0)
    hi = np.max([p.bounds[2:] for p in polys], axis=0)
    centre = (lo + hi) / 2
    found: list[np.ndarray] = []
    for a, pa in enumerate(polys):
        for b, pb in enumerate(polys):
            if a == b or not _similar_area(pa, pb, min_iou):
                continue
            off = cents[b] - cents[a]
            if _iou(affinity.translate(pa, off[0], off[1]), pb) >= min_iou:
                continue  # a translated copy: the translational probe's business
            for deg in QUARTER_TURNS:
                g = _pair_motion(cents[a], cents[b], np.deg2rad(deg))
                if _iou(_moved(pa, g), pb) >= min_iou:
                    found.append(g)
    uniq: list[np.ndarray] = []
    for g in found:
        at = _apply(g, centre)
        if all(
            np.hypot(*(at - _apply(u, centre))) > dedupe
            or abs(np.angle(np.exp(1j * (g[2] - u[2])))) > angle_tol
            for u in uniq
        ):
            uniq.append(g)
    support = np.array([motion_support(polys, g, min_iou) for g in uniq], np.int64)
    order = np.argsort(-support, kind="stable")
    return np.asarray(uniq, np.float64).reshape(-1, 3)[order], support[order]


def _apply(g: np.ndarray, p: np.ndarray) -> np.ndarray:
    c, s = np.cos(g[2]), np.sin(g[2])
    return np.array([c * p[0] - s * p[1] + g[0], s * p[0] + c * p[1] + g[1]])
