"""Occupancy-aware verification score of a candidate pose ``Y = ^B T_S``, continuous in ``Y``.

With ``d(.)`` the floor plan's *signed* distance to the wall surface (m, negative inside wall
solid, exact near walls), ``pen(.)`` a free-space penalty field, submap points ``p_k`` (occupied)
and free-space samples ``q_l`` taken along each ray sensor origin -> point, stopping ``ray_stop``
metres short of the point:

    s(Y; sigma) = 1/|P| sum_k exp(-d(Y p_k)^2 / (2 sigma^2))
                - lambda_free / |Q| sum_l pen(Y q_l),
    pen = max(exp(-max(d, 0)^2 / (2 sigma_free^2)), outside * (1 - inside))

The first term (in [0, 1]) rewards occupied points that land on plan wall *surfaces*. The second
(in [0, lambda_free]) penalises space the LiDAR saw through that the plan calls wall or outside
the building (``outside`` = 1; an occupancy map's never-observed outside counts half,
``Rasters.outside``). Points occupied in the submap but free in the plan (furniture, as-built
additions) only miss the reward; they are never penalised.

Both fields are sampled bilinearly, so ``s`` is continuous and piecewise smooth in ``Y`` and
resolves poses well below the 0.10 m raster cell. The kernel is applied *after* interpolating
the signed distance (interpolating a kernel raster, or an unsigned distance, would flatten the
peak at the wall surface to a cell-wide plateau). The same function ranks the voted poses,
drives the refinement (``refine.py``, which maximises its first term by reweighted Gauss-Newton)
and decides whether a refined pose is kept.

Sampling cost: each field is stored as ``(H + 1, W + 1, 4)``, the four bilinear neighbours of
every cell side by side (``stack4``), so one sample reads one 16-byte cell (four scalar gathers
from one cache line).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import shapely
from scipy import ndimage

from mfcl_jax.frontend.materialize import materialize

__all__ = [
    "FAR",
    "block_scores",
    "block_terms",
    "term_means",
    "free_samples",
    "surface_fields",
    "stack4",
    "sample",
    "sample_xy",
    "occupancy",
    "point_terms",
    "rotation",
    "score",
    "score_fields",
    "scores",
]

FAR = 10.0  # signed distance read off the grid (m): no reward there


def free_samples(pts, org, ok, n_samples: int, stop: float):
    """Free-space samples along each ray, in the submap frame.

    Args:
        pts: ``(n, 2)`` points; ``org`` ``(n, 2)`` sensor origins; ``ok`` ``(n,)`` mask.
        n_samples: static samples per ray, at fractions ``k / n_samples`` of the free length.
        stop: metres kept free of samples before each point (range noise, grazing rays).

    Returns:
        ``(q (n * n_samples, 2), q_ok (n * n_samples,))``.
    """
    ray = pts - org
    length = jnp.sqrt(jnp.sum(ray * ray, -1))
    free_len = length - stop
    safe = jnp.where(length > 1e-6, length, 1.0)
    f = jnp.arange(n_samples, dtype=jnp.float32) / n_samples  # (M,)
    q = org[:, None, :] + (f[None, :, None] * (free_len / safe)[:, None, None]) * ray[:, None, :]
    q_ok = jnp.broadcast_to((ok & (free_len > 0))[:, None], q.shape[:2])
    # Scoring reads every sample once per candidate pose: compute them once (materialize).
    qx, qy, q_ok = materialize(q[..., 0].reshape(-1), q[..., 1].reshape(-1), q_ok.reshape(-1))
    return jnp.stack([qx, qy], -1), q_ok


def surface_fields(fp, rasters, sigma_free: float, band: float = 0.6):
    """Host: signed wall-surface distance and free-space penalty on the raster grid.

    The sign comes from the raster's wall mask (cell-centre containment); the magnitude is the
    exact distance to the wall-solid boundary for cells within ``band`` of it (when ``fp`` is
    given), and the raster's Euclidean distance transform elsewhere.

    Args:
        fp: ``Floorplan`` or None (then the distance is raster-based, +-half a cell).
        rasters: NumPy ``Rasters`` (possibly padded).
        sigma_free: width of the penalty kernel (m).

    Returns:
        ``(sdf (H, W), penalty (H, W))`` float32.
    """
    wall = np.asarray(rasters.wall, bool)
    res = float(rasters.res)
    out = np.asarray(rasters.dist, np.float64)
    if wall.any():
        inner = np.maximum(ndimage.distance_transform_edt(wall) * res - 0.5 * res, 0.0)
        sdf = np.where(wall, -inner, out)
    else:
        sdf = out
    if fp is not None and wall.any():
        near = np.abs(sdf) < band
        iy, ix = np.nonzero(near)
        x = rasters.origin[0] + res * (ix + 0.5)
        y = rasters.origin[1] + res * (iy + 0.5)
        exact = shapely.distance(fp.wall_solid.boundary, shapely.points(x, y))
        sdf[iy, ix] = np.where(wall[iy, ix], -exact, exact)
    sdf = np.minimum(sdf, FAR)
    pen = np.maximum(
        np.exp(-0.5 * (np.maximum(sdf, 0.0) / sigma_free) ** 2),
        float(rasters.outside) * (1.0 - np.asarray(rasters.inside, float)),
    )
    return sdf.astype(np.float32), pen.astype(np.float32)


def stack4(grid, fill: float) -> np.ndarray:
    """Host: ``(H, W)`` -> ``(H + 1, W + 1, 4)``; entry ``[i, j]`` holds the grid values at
    ``(i - 1, j - 1), (i - 1, j), (i, j - 1), (i, j)`` (``fill`` off the grid)."""
    g = np.pad(np.asarray(grid, np.float32), 1, constant_values=fill)
    return np.stack([g[:-1, :-1], g[:-1, 1:], g[1:, :-1], g[1:, 1:]], -1)


def rotation(poses):
    """``(cos, sin)`` of the headings of ``poses (K, 3)``, each ``(K,)``, computed once per pose
    (``materialize``), not once per point of the loops that read them."""
    return materialize(jnp.cos(poses[:, 2]), jnp.sin(poses[:, 2]))


def _transform(pose, rot, x, y):
    """World coordinates of submap points ``x, y (n,)`` under one pose ``(3,)`` with ``rot`` its
    ``(cos, sin)``: the components apart (an ``(n, 2)`` layout costs XLA:CPU a stack, a
    materialised copy and tiny reductions)."""
    c, s = (jnp.cos(pose[2]), jnp.sin(pose[2])) if rot is None else rot
    return c * x - s * y + pose[0], s * x + c * y + pose[1]


def sample_xy(origin, res: float, field4, x, y, fill: float, grad: bool = False):
    """Bilinear sample of a ``stack4`` field at world points ``(x, y)``, each ``(*)``.

    The four neighbours are four scalar gathers from one 16-byte cell (one cache line): on
    XLA:CPU that is half the cost of one gather of a 4-vector.

    Args:
        origin: ``(2,)`` raster origin; ``res`` static cell size.
        field4: ``(H + 1, W + 1, 4)`` from ``stack4``.
        x, y: coordinates (m), same shape.
        fill: value off the grid.
        grad: also return the spatial gradient ``(gx, gy)`` (per m), 0 off the grid.

    Returns:
        ``v`` or ``(v, gx, gy)``, each of the shape of ``x``. Differentiable in ``x, y``.
    """
    inv = 1.0 / res  # a product, not a division: scalar divisions dominate the refinement loop
    fx = (x - origin[0]) * inv - 0.5
    fy = (y - origin[1]) * inv - 0.5
    x0, y0 = jnp.floor(fx), jnp.floor(fy)
    ax, ay = fx - x0, fy - y0
    ix, iy = x0.astype(jnp.int32) + 1, y0.astype(jnp.int32) + 1
    h, w = field4.shape[0], field4.shape[1]
    ok = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    # Clipped, so in bounds; unsigned, so no negative-index wrap-around per gather.
    k = (4 * (jnp.clip(iy, 0, h - 1) * w + jnp.clip(ix, 0, w - 1))).astype(jnp.uint32)
    flat = field4.reshape(-1)
    c0, c1, c2, c3 = (flat.at[k + j].get(mode="promise_in_bounds") for j in range(4))
    lo = c0 + ax * (c1 - c0)
    hi = c2 + ax * (c3 - c2)
    v = jnp.where(ok, lo + ay * (hi - lo), fill)
    if not grad:
        return v
    gx = jnp.where(ok, (1 - ay) * (c1 - c0) + ay * (c3 - c2), 0.0) * inv
    gy = jnp.where(ok, hi - lo, 0.0) * inv
    return v, gx, gy


def sample(origin, res: float, field4, xy, fill: float, grad: bool = False):
    """Bilinear sample of a ``stack4`` field at world points ``xy (*, 2)`` (``sample_xy``).

    Returns:
        ``v (*,)`` or ``(v, g)`` with the spatial gradient ``g (*, 2)`` (per m).
    """
    out = sample_xy(origin, res, field4, xy[..., 0], xy[..., 1], fill, grad)
    if not grad:
        return out
    v, gx, gy = out
    return v, jnp.stack([gx, gy], -1)


def _mean(v, ok):
    return jnp.sum(jnp.where(ok, v, 0.0)) / jnp.maximum(jnp.sum(ok).astype(v.dtype), 1.0)


def _dot_mean(v, ok):
    """``_mean`` as a dot product with the mask: XLA:CPU runs a sum fused with the lookups'
    gathers as a scalar loop, a dot it keeps apart (``path_search._score``)."""
    w = ok.astype(v.dtype)
    return jnp.dot(jnp.where(ok, v, 0.0), w) / jnp.maximum(jnp.sum(w), 1.0)


def occupancy(pose, pts, ok, feats, sigma, rot=None):
    """First term of ``s``: mean wall-surface kernel over the occupied points, in [0, 1].

    ``rot``: the pose's ``(cos, sin)`` from ``rotation``, or None to compute them here.
    """
    r = feats.rasters
    x, y = _transform(pose, rot, pts[:, 0], pts[:, 1])
    d = sample_xy(r.origin, r.res, feats.sdf4, x, y, FAR)
    return _mean(jnp.exp(-0.5 * (d / sigma) ** 2), ok)


def score(pose, pts, ok, q, q_ok, feats, sigma, lam, rot=None):
    """Verification score ``s(Y; sigma)`` of one pose (module docstring).

    Args:
        pose: ``(3,)`` candidate ``^B T_S``.
        pts: ``(n, 2)`` occupied points (submap frame), ``ok`` their mask.
        q: ``(m, 2)`` free-space samples, ``q_ok`` their mask.
        feats: ``FloorplanFeatures`` (``sdf4``, ``pen4``, rasters geometry).
        sigma: occupancy kernel width (m); lam: free-space weight ``lambda_free``.
        rot: the pose's ``(cos, sin)`` from ``rotation``, or None to compute them here.

    Returns:
        Scalar score in ``[-lam, 1]``; 0 when there are no points.
    """
    r = feats.rasters
    x, y = _transform(pose, rot, q[:, 0], q[:, 1])
    pen = sample_xy(r.origin, r.res, feats.pen4, x, y, 1.0)
    return occupancy(pose, pts, ok, feats, sigma, rot) - lam * _mean(pen, q_ok)


def point_terms(pose, pts, q, origin, res, sdf4, pen4, sigma):
    """The terms ``score_fields`` averages, per point: ``(hit (n,), pen (m,))``, the
    wall-surface kernel of each point and the free-space penalty of each free sample."""
    x, y = _transform(pose, None, pts[:, 0], pts[:, 1])
    d = sample_xy(origin, res, sdf4, x, y, FAR)
    qx, qy = _transform(pose, None, q[:, 0], q[:, 1])
    return jnp.exp(-0.5 * (d / sigma) ** 2), sample_xy(origin, res, pen4, qx, qy, 1.0)


def score_fields(pose, pts, ok, q, q_ok, origin, res, sdf4, pen4, sigma, lam):
    """``score`` with the fields given explicitly (``origin (2,)``, static ``res``, ``sdf4``,
    ``pen4``), for callers that hold them outside ``FloorplanFeatures`` (the certification)."""
    hit, pen = point_terms(pose, pts, q, origin, res, sdf4, pen4, sigma)
    h, p = term_means(hit, pen, ok, q_ok)
    return h - lam * p


def term_means(hit, pen, ok, q_ok):
    """The two means ``score_fields`` weighs: ``(mean hit over ok, mean pen over q_ok)``."""
    return _dot_mean(hit, ok), _dot_mean(pen, q_ok)


def block_scores(hit, pen, ok, q_ok, n_blocks: int, lam):
    """``score_fields`` of ``n_blocks`` contiguous blocks of the points (by rank among the
    valid points ``ok (n,)``, each block with its points' free samples ``q_ok (n * M,)``,
    each point's samples together, as ``free_samples`` lays them out); ``(n_blocks,)``."""
    hit_mean, pen_mean = block_terms(hit, pen, ok, q_ok, n_blocks)
    return hit_mean - lam * pen_mean


def block_terms(hit, pen, ok, q_ok, n_blocks: int):
    """``term_means`` of each block of ``block_scores``: ``(hit (n_blocks,), pen (n_blocks,))``."""
    n = ok.shape[0]
    rank = jnp.cumsum(ok) - 1
    block = jnp.where(ok, (rank * n_blocks) // jnp.maximum(jnp.sum(ok), 1), -1)
    # one-hot sums: each term is read once (a per-block masked mean let XLA:CPU recompute
    # the field lookups feeding it once per block, 4x the cost of the whole fitted scoring)
    onehot = (block[:, None] == jnp.arange(n_blocks)).astype(hit.dtype)  # (n, B)
    onehot_q = jnp.where(q_ok[:, None], jnp.repeat(onehot, q_ok.shape[0] // n, axis=0), 0.0)
    hit_mean = (jnp.where(ok, hit, 0.0) @ onehot) / jnp.maximum(onehot.sum(0), 1.0)
    pen_mean = (jnp.where(q_ok, pen, 0.0) @ onehot_q) / jnp.maximum(onehot_q.sum(0), 1.0)
    return hit_mean, pen_mean


def scores(poses, pts, ok, q, q_ok, feats, sigma, lam):
    """``score`` of every pose of ``poses (K, 3)`` against one submap; ``(K,)``."""
    c, s = rotation(poses)
    one = lambda y, c, s: score(y, pts, ok, q, q_ok, feats, sigma, lam, (c, s))  # noqa: E731
    return jax.vmap(one)(poses, c, s)
