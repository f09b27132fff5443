"""Furniture: axis-aligned rectangles that the LiDAR sees and the floor plan does not.

Items are placed by rejection inside the rooms' clear interiors, away from every walk (the
polyline and the smoothed path the simulator drives), from door openings and from whatever is
already there; about half of them are pushed against a wall (cabinets, desks), the rest stand
free (tables). When random items stop fitting, a tighter grid of desk-sized items fills what is
left, so that high densities (up to half the floor) are reachable where the walks leave room.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString, MultiLineString, Polygon
from shapely.ops import unary_union

from mfcl_jax.sim.scenes import rect_segments
from mfcl_jax.sim.trajectory import sample_path

__all__ = ["furnish", "door_zone", "WALK_KEEP_OUT"]

# Furniture keeps this far (m) from every walk.
WALK_KEEP_OUT = 0.5
# ... and out of a box round each door: this far along the wall from the door's centre and this
# far from the wall's centre line on both sides (the door's swing and approach).
_DOOR_ALONG, _DOOR_ACROSS = 1.2, 1.4
_GAP = 0.06  # between two items


def furnish(fp, walks, fraction: float, rng: np.random.Generator, world=None, existing=None):
    """Places furniture covering about ``fraction`` of the floor area.

    Args:
        fp: the ``Floorplan`` (its rooms are the floor; its doors are kept clear).
        walks: iterable of ``(P, 2)`` waypoint polylines to keep clear.
        fraction: target area fraction of the floor, in ``[0, 0.5]``.
        rng: the generator.
        world: ``(F, 2, 2)`` wall faces the LiDAR sees where they differ from the plan's
            (items never cross them); ``None``: the plan's walls (the rooms already avoid them).
        existing: ``(K, 2, 2)`` clutter already there (items neither cross nor hide in it).

    Returns:
        ``(segments (4 N, 2, 2), achieved)``: the items' sides and the area fraction they cover.
    """
    floor = unary_union([r.polygon for r in fp.rooms])
    area = sum(r.polygon.area for r in fp.rooms)
    target = fraction * area
    if target <= 0:
        return np.zeros((0, 2, 2)), 0.0
    allowed = floor.difference(_keep_out(fp, walks, world, existing))
    shapely.prepare(allowed)
    placed: list = []
    total = 0.0
    room_bounds = [r.polygon.bounds for r in fp.rooms]
    # Random items first (half of them against a wall), then a grid fill.
    for _ in range(12):
        if total >= target:
            break
        cand = _random_items(rng, room_bounds, 160)
        total = _accept(cand, allowed, placed, total, target)
    for pitch in (1.6, 1.25, 1.0, 0.8, 0.6, 0.6):
        if total >= target:
            break
        cand = _grid_items(rng, allowed.bounds, pitch)
        total = _accept(cand, allowed, placed, total, target)
    segs = [rect_segments(*b) for b in placed]
    out = np.concatenate(segs) if segs else np.zeros((0, 2, 2))
    return out, total / area


def _keep_out(fp, walks, world, existing):
    parts = []
    for wp in walks:
        wp = np.asarray(wp, float)
        path = LineString(sample_path(wp).poses[:, :2]).simplify(0.01)
        parts.append(LineString(wp).buffer(WALK_KEEP_OUT, quad_segs=4))
        parts.append(path.buffer(WALK_KEEP_OUT, quad_segs=4))
    for d in fp.doors:
        parts.append(door_zone(d.segment))
    if world is not None and len(world):
        parts.append(MultiLineString(list(np.asarray(world, float))).buffer(0.03, quad_segs=2))
    if existing is not None and len(existing):
        lines = MultiLineString(list(np.asarray(existing, float)))
        parts.append(lines.buffer(_GAP))
        parts.extend(shapely.get_parts(shapely.polygonize(shapely.get_parts(lines))))
    return unary_union(parts)


def door_zone(segment) -> Polygon:
    """The box kept free of furniture round a door (``segment`` runs across the opening)."""
    seg = np.asarray(segment, float)
    c, n = seg.mean(0), seg[1] - seg[0]
    n = n / np.linalg.norm(n)
    u = np.array([-n[1], n[0]]) * _DOOR_ALONG
    n = n * _DOOR_ACROSS
    return Polygon([c - u - n, c + u - n, c + u + n, c - u + n])


def _random_items(rng, room_bounds, n):
    """``n`` random items in random rooms, about half pushed against a wall of their room."""
    rb = np.asarray(room_bounds)[rng.integers(len(room_bounds), size=n)]
    w = rng.uniform(0.5, 2.4, n)
    h = rng.uniform(0.4, 1.2, n)
    swap = rng.random(n) < 0.5
    w, h = np.where(swap, h, w), np.where(swap, w, h)
    x = rng.uniform(rb[:, 0], np.maximum(rb[:, 0], rb[:, 2] - w))
    y = rng.uniform(rb[:, 1], np.maximum(rb[:, 1], rb[:, 3] - h))
    # Against the nearest side of the room's box (flush with its wall face).
    side = rng.integers(4, size=n)
    wall = rng.random(n) < 0.5
    x = np.where(wall & (side == 0), rb[:, 0] + 0.02, x)
    x = np.where(wall & (side == 1), rb[:, 2] - w - 0.02, x)
    y = np.where(wall & (side == 2), rb[:, 1] + 0.02, y)
    y = np.where(wall & (side == 3), rb[:, 3] - h - 0.02, y)
    return shapely.box(x, y, x + w, y + h)


def _grid_items(rng, bounds, pitch):
    """Desk-sized items on a grid of ``pitch`` over ``bounds``, in random order."""
    x0, y0, x1, y1 = bounds
    ox, oy = rng.uniform(0, pitch, 2)
    gx, gy = np.meshgrid(np.arange(x0 - ox, x1, pitch), np.arange(y0 - oy, y1, pitch))
    gx, gy = gx.ravel(), gy.ravel()
    m = pitch - _GAP - 0.05
    items = shapely.box(gx, gy, gx + m, gy + m)
    return items[rng.permutation(len(items))]


def _accept(cand, allowed, placed, total, target) -> float:
    """Adds the candidates that fit (inside ``allowed``, apart from ``placed``) up to ``target``.

    ``placed`` holds item bounds ``(x0, y0, x1, y1)``; items are axis-aligned boxes, so two of
    them are apart by ``_GAP`` exactly when their bounds are.
    """
    cand = shapely.bounds(cand[shapely.contains(allowed, cand)])
    for b in cand:
        if total >= target:
            break
        if placed:
            p = np.asarray(placed)
            clash = (
                (b[0] < p[:, 2] + _GAP)
                & (p[:, 0] < b[2] + _GAP)
                & (b[1] < p[:, 3] + _GAP)
                & (p[:, 1] < b[3] + _GAP)
            )
            if clash.any():
                continue
        placed.append(tuple(b))
        total += (b[2] - b[0]) * (b[3] - b[1])
    return total
