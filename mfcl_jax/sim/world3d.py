"""The 3-D world of a floor plan for the multi-ring LiDAR: extruded walls, floor, ceiling, boxes.

Every 2-D wall face becomes a vertical rectangle from the floor ``z = 0`` to the ceiling
``z = h_ceil``; the floor and the ceiling are unbounded horizontal planes; a clutter segment is
extruded to its own height (a vertical face), and every closed chain of clutter segments of one
height (a box footprint, ``scenes.rect_segments``) also gets a horizontal lid at that height (a
table top). An open chain (a partition) has faces only. Door openings are floor-to-ceiling
gaps: the plan has no lintels.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import shapely
from shapely.geometry import Polygon

__all__ = ["Geometry3D", "build_geometry", "first_hit", "nearest_faces"]

DEFAULT_CLUTTER_HEIGHT = 1.0  # m: furniture height when a scene gives none


class Geometry3D(NamedTuple):
    """What the 3-D beams can hit (padded; build with ``build_geometry``).

    Attributes:
        faces: ``(M, 2, 2)`` vertical faces' footprints.
        face_top: ``(M,)`` top of each face (m); faces span ``[0, face_top]``.
        face_valid: ``(M,)`` bool.
        caps: ``(C, 3, 2)`` horizontal triangles (box lids).
        cap_z: ``(C,)`` height of each triangle (m).
        cap_valid: ``(C,)`` bool.
        h_ceil: ceiling height (m), a float32 scalar.
    """

    faces: jax.Array
    face_top: jax.Array
    face_valid: jax.Array
    caps: jax.Array
    cap_z: jax.Array
    cap_valid: jax.Array
    h_ceil: jax.Array


def _closed_chains(segs: np.ndarray, heights: np.ndarray, tol: float = 1e-6) -> list:
    """``(first, last)`` index ranges of runs of consecutive segments forming a closed loop of
    one height (each segment starts where the previous one ends, the last ends at the first)."""
    out, i, n = [], 0, len(segs)
    while i < n:
        j = i
        while True:
            if j > i + 1 and np.allclose(segs[j, 1], segs[i, 0], atol=tol):
                out.append((i, j))
                i = j + 1
                break
            if j + 1 < n and np.allclose(segs[j, 1], segs[j + 1, 0], atol=tol):
                if heights[j + 1] == heights[i]:
                    j += 1
                    continue
            i += 1
            break
    return out


def _pad(a: np.ndarray, n: int, fill=0.0) -> np.ndarray:
    out = np.full((n, *a.shape[1:]), fill, a.dtype)
    out[: len(a)] = a
    return out


def build_geometry(walls, clutter=None, clutter_height=None, h_ceil: float = 2.8) -> Geometry3D:
    """The 3-D world of a floor plan's wall faces and clutter (host; pads to multiples of 64).

    Args:
        walls: ``(F, 2, 2)`` wall faces (``Floorplan.wall_faces``), extruded floor to ceiling.
        clutter: ``(K, 2, 2)`` clutter segments (``Scene.clutter``) or ``None``.
        clutter_height: ``(K,)`` heights (m; ``inf`` or above ``h_ceil``: to the ceiling);
            ``None``: ``DEFAULT_CLUTTER_HEIGHT`` each.
        h_ceil: ceiling height above the floor (m).
    """
    walls = np.asarray(walls, np.float64).reshape(-1, 2, 2)
    clutter = np.zeros((0, 2, 2)) if clutter is None else np.asarray(clutter, float)
    clutter = clutter.reshape(-1, 2, 2)
    if clutter_height is None:
        clutter_height = np.full(len(clutter), DEFAULT_CLUTTER_HEIGHT)
    ch = np.asarray(clutter_height, np.float64).reshape(-1)
    if ch.shape != (len(clutter),) or not np.all(ch > 0):
        raise ValueError(f"clutter_height: need {len(clutter)} heights > 0, got {ch}")
    if not (np.isfinite(h_ceil) and h_ceil > 0):
        raise ValueError(f"build_geometry: h_ceil must be a positive number, got {h_ceil!r}")
    ch = np.minimum(ch, h_ceil)
    faces = np.concatenate([walls, clutter])
    top = np.concatenate([np.full(len(walls), h_ceil), ch])
    tris, tri_z = [], []
    for i, j in _closed_chains(clutter, ch):
        if ch[i] >= h_ceil:  # a box up to the ceiling: its lid is the ceiling
            continue
        poly = Polygon(clutter[i : j + 1, 0])
        if not poly.is_valid or poly.area <= 0:
            continue
        for t in shapely.constrained_delaunay_triangles(poly).geoms:
            tris.append(np.asarray(t.exterior.coords)[:3])
            tri_z.append(ch[i])
    tris = np.asarray(tris, np.float64).reshape(-1, 3, 2)
    m_cap = -(-max(len(faces), 1) // 64) * 64
    c_cap = -(-max(len(tris), 1) // 64) * 64
    f32 = np.float32
    return Geometry3D(
        faces=jnp.asarray(_pad(faces.astype(f32), m_cap)),
        face_top=jnp.asarray(_pad(top.astype(f32), m_cap)),
        face_valid=jnp.asarray(np.arange(m_cap) < len(faces)),
        caps=jnp.asarray(_pad(tris.astype(f32), c_cap)),
        cap_z=jnp.asarray(_pad(np.asarray(tri_z, f32), c_cap)),
        cap_valid=jnp.asarray(np.arange(c_cap) < len(tris)),
        h_ceil=jnp.float32(h_ceil),
    )


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def first_hit(origin, dirs, g: Geometry3D):
    """Range to the first surface along ``dirs (n, 3)`` from ``origin (3,)``; inf if none."""
    dh, dz = dirs[:, :2], dirs[:, 2:3]
    # Vertical faces: the 2-D crossing of the beam's footprint, then the height at that range.
    a = g.faces[:, 0]
    e = g.faces[:, 1] - a
    w = a - origin[:2]
    den = _cross(dh[:, None, :], e[None])  # (n, M)
    ok = (jnp.abs(den) > 1e-9) & g.face_valid[None]
    safe = jnp.where(ok, den, 1.0)
    t = _cross(w, e)[None] / safe
    u = _cross(w[None], dh[:, None, :]) / safe
    z = origin[2] + t * dz
    # The u slack closes the cracks where two faces meet (as in the 2-D caster).
    hit = ok & (t > 0) & (u >= -1e-5) & (u <= 1 + 1e-5) & (z >= 0) & (z <= g.face_top[None])
    r = jnp.min(jnp.where(hit, t, jnp.inf), axis=1)
    # Lids: the beam meets the plane z = cap_z, then a point-in-triangle test (same side of
    # all three edges, either orientation).
    down = jnp.abs(dz) > 1e-9
    dz_safe = jnp.where(down, dz, 1.0)
    tc = (g.cap_z[None] - origin[2]) / dz_safe  # (n, C)
    q = origin[:2] + tc[..., None] * dh[:, None, :]  # (n, C, 2)
    v = g.caps  # (C, 3, 2)
    s = jnp.stack([_cross(v[:, (k + 1) % 3] - v[:, k], q - v[:, k]) for k in range(3)], -1)
    inside = jnp.all(s >= -1e-9, -1) | jnp.all(s <= 1e-9, -1)
    hit_c = down & g.cap_valid[None] & (tc > 0) & inside
    r = jnp.minimum(r, jnp.min(jnp.where(hit_c, tc, jnp.inf), axis=1))
    # Floor z = 0 and ceiling z = h_ceil.
    t_floor = jnp.where(dz[:, 0] < -1e-9, -origin[2] / dz_safe[:, 0], jnp.inf)
    t_ceil = jnp.where(dz[:, 0] > 1e-9, (g.h_ceil - origin[2]) / dz_safe[:, 0], jnp.inf)
    return jnp.minimum(r, jnp.minimum(t_floor, t_ceil))


def nearest_faces(g: Geometry3D, xy, k: int):
    """``g`` cut to the ``k`` faces nearest to ``xy (2,)``, and the distance beyond which a
    face may be missing (inf when none was cut). Static ``k``; ``k >= M`` keeps all."""
    m = g.faces.shape[0]
    if k >= m:
        return g, jnp.float32(jnp.inf)
    a = g.faces[:, 0]
    e = g.faces[:, 1] - a
    u = jnp.clip(jnp.sum((xy - a) * e, -1) / jnp.maximum(jnp.sum(e * e, -1), 1e-12), 0.0, 1.0)
    d = jnp.linalg.norm(xy - (a + u[:, None] * e), axis=-1)
    neg, idx = jax.lax.top_k(-jnp.where(g.face_valid, d, jnp.inf), k)
    cut = g._replace(faces=g.faces[idx], face_top=g.face_top[idx], face_valid=g.face_valid[idx])
    return cut, -neg[k - 1]
