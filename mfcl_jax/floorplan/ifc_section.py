"""Horizontal sections of triangle meshes: the cut the IFC loader takes through each solid.

A cut is exact for a closed triangle mesh: each triangle that straddles the plane contributes
one segment, the segments close into loops, and the loops are polygonised with the even-odd
rule (a face is solid if a ray from it crosses an odd number of section segments).
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.ops import unary_union

__all__ = ["section_mesh", "polygon_parts"]


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


def polygon_parts(geom) -> list[Polygon]:
    """The non-empty polygons of a section (made valid first); ``[]`` for ``None``."""
    if geom is None or geom.is_empty:
        return []
    if not geom.is_valid:
        geom = shapely.make_valid(geom)
    return [g for g in shapely.get_parts(geom) if isinstance(g, Polygon) and not g.is_empty]
