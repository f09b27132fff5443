"""The outline of a floor plan's wall solid: its rings, boundary segments and corners.

Host-side (NumPy + shapely), read by ``Floorplan.wall_faces`` and ``Floorplan.corners``.
"""

from __future__ import annotations

import math

import numpy as np
from shapely.geometry import MultiPolygon

from mfcl_jax.se2 import wrap_host

__all__ = ["rings", "boundary_segments", "wall_corners", "CORNER_SIMPLIFY", "MAX_CORNERS"]

# Wall corners (``Floorplan.corners``): boundary simplification (m) and the most kept.
CORNER_SIMPLIFY = 0.05
MAX_CORNERS = 512


def wall_corners(solid) -> tuple[np.ndarray, np.ndarray]:
    """The corners of a wall solid's boundary, the most salient first (``Floorplan.corners``).

    Args:
        solid: the wall solid, a shapely (Multi)Polygon.

    Returns:
        ``(points (C, 2), directions (C, 2))``: each corner's position and the angles (rad)
        of its two boundary edges, pointing away from the corner; most salient first.
    """
    pts, dirs, sal = [], [], []
    for ring in rings(solid.simplify(CORNER_SIMPLIFY)):
        xy = np.asarray(ring.coords)[:-1]
        n = len(xy)
        for i in range(n):
            p, a, b = xy[i], xy[i - 1], xy[(i + 1) % n]
            da, db = a - p, b - p
            la, lb = float(np.linalg.norm(da)), float(np.linalg.norm(db))
            if la < 1e-6 or lb < 1e-6:
                continue
            ang_a, ang_b = math.atan2(da[1], da[0]), math.atan2(db[1], db[0])
            between = abs(float(wrap_host(ang_a - ang_b)))
            if between > math.radians(160):
                continue
            pts.append(p)
            dirs.append((ang_a, ang_b))
            sal.append(min(la, lb))
    pts = np.asarray(pts, float).reshape(-1, 2)
    dirs = np.asarray(dirs, float).reshape(-1, 2)
    keep = np.argsort(-np.asarray(sal), kind="stable")[:MAX_CORNERS]  # most salient first
    return pts[keep].reshape(-1, 2), dirs[keep].reshape(-1, 2)


def rings(geom) -> list:
    """The exterior and interior rings of a (Multi)Polygon, empty parts skipped."""
    polys = geom.geoms if isinstance(geom, MultiPolygon) else [geom]
    out = []
    for p in polys:
        if p.is_empty:
            continue
        out.append(p.exterior)
        out.extend(p.interiors)
    return out


def boundary_segments(geom) -> np.ndarray:
    """The boundary of a (Multi)Polygon as segments ``(F, 2, 2)``, ring by ring."""
    segs = []
    for ring in rings(geom):
        xy = np.asarray(ring.coords)
        segs.extend(np.stack([xy[:-1], xy[1:]], axis=1))
    return np.asarray(segs, float).reshape(-1, 2, 2)
