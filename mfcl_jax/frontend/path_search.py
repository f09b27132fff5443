"""Global search for rigid placements of a whole accumulated path in the floor plan.

Given scans placed in one frame ``F`` (by odometry, or by any other poses), find the rigid
motions ``g: F -> B`` under which the path explains the plan best, anywhere in the building,
without a prior. It serves the scorer (alternative explanations of a run, from ground truth)
and the decision layer (competitors of a commit, from odometry); it sees only the cloud and
the plan.

Two stages:

1. Coarse, exhaustive: for every heading on a ``yaw_step_deg`` grid, the rotated cloud is
   splatted into an image at ``coarse_res`` and cross-correlated (FFT) with two plan fields:
   a wall-proximity field ``exp(-d^2 / 2 sigma^2)`` (``d``: distance to the nearest wall
   solid, block-minimum) rewarding points, and an obstacle field (share of wall or
   out-of-building cells) penalising ray samples and sensor positions. Every translation of
   every heading is scored at once; local maxima per heading are kept.
2. Fine, local: the best coarse peaks (after suppressing near-duplicates) are polished by two
   rounds of local grid search on the fine rasters (bilinear lookups, ``sigma_fine``).

Scores are means: ``hit`` (mean wall proximity of the points) minus ``lam`` times ``bad`` (the
mean obstacle value of ray samples and sensor positions), so clutter that the plan lacks is
neither rewarded nor punished, while a placement that puts the robot in a wall or its rays
through walls is.

The settings and the plan fields are in ``path_fields``, the per-scan statistics of given
placements (``evaluate_placements``) in ``placements``; both are re-exported here.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.frontend.path_fields import PlanFields, SearchParams, plan_fields, sample_field
from mfcl_jax.frontend.placements import evaluate_placements

__all__ = [
    "SearchParams",
    "PlanFields",
    "plan_fields",
    "search",
    "uncentre",
    "evaluate_placements",
    "splat",
    "map_peaks",
    "polish",
    "refine_placement",
    "nms",
    "fft_size",
    "corr_size",
]


def _score(g, pts, pok, frees, fok, fields, lam):
    """Fine score of placement ``g (3,)``: mean hit of points minus ``lam`` mean bad."""
    hit = sample_field(fields.hit, fields.origin, fields.res, se2.apply(g, pts), 0.0)
    bad = sample_field(fields.bad, fields.origin, fields.res, se2.apply(g, frees), fields.outside)
    # sums as dot products with the masks: XLA:CPU runs a reduction fused with the lookups'
    # gathers as a scalar loop, a dot it does not fuse (3.4x faster on the polish's batches)
    mh = jnp.dot(jnp.where(pok, hit, 0.0), pok.astype(hit.dtype)) / jnp.maximum(
        jnp.sum(pok), 1
    ).astype(hit.dtype)
    mb = jnp.dot(jnp.where(fok, bad, 0.0), fok.astype(bad.dtype)) / jnp.maximum(
        jnp.sum(fok), 1
    ).astype(bad.dtype)
    return mh - lam * mb


def splat(xy, ok, n, res, half):
    """Bilinear splat of points ``xy (M, 2)`` (centred) into an ``(n, n)`` image."""
    u = (xy[:, 0] + half) / res - 0.5
    v = (xy[:, 1] + half) / res - 0.5
    u0, v0 = jnp.floor(u), jnp.floor(v)
    fu, fv = u - u0, v - v0
    u0, v0 = u0.astype(jnp.int32), v0.astype(jnp.int32)
    img = jnp.zeros((n * n,), jnp.float32)
    for du, dv, wgt in ((0, 0, (1 - fu) * (1 - fv)), (1, 0, fu * (1 - fv)), (0, 1, (1 - fu) * fv),
                        (1, 1, fu * fv)):  # fmt: skip
        iu, iv = u0 + du, v0 + dv
        good = ok & (iu >= 0) & (iu < n) & (iv >= 0) & (iv < n)
        img = img.at[jnp.where(good, iv * n + iu, 0)].add(jnp.where(good, wgt, 0.0))
    return img.reshape(n, n)


def map_peaks(sc, th, plan_shape, n_img: int, res: float, origin, k: int):
    """The ``k`` best local maxima (5 x 5 cells) of one heading's correlation map.

    Args:
        sc: ``(fh, fw)`` score per shift (``corr_size``), stored modulo the map size (shift
            ``s`` of the centred cloud image against the plan grid: a stored index
            ``i >= Hc`` is the shift ``i - fh``).
        th: the heading; plan_shape: ``(Hc, Wc)`` coarse plan grid; n_img: cloud image side;
        res: coarse cell (m); origin: ``(2,)`` plan grid corner; k: peaks kept (static).

    Returns:
        ``(poses (k, 3), vals (k,))``: placements of the centred cloud; shifts that move the
        cloud's centre outside the plan grid are not placements (``-inf``).
    """
    hc, wc = plan_shape
    fh, fw = sc.shape
    half = n_img * res / 2
    sy = jnp.where(jnp.arange(fh) < hc, jnp.arange(fh), jnp.arange(fh) - fh)
    sx = jnp.where(jnp.arange(fw) < wc, jnp.arange(fw), jnp.arange(fw) - fw)
    cy = sy[:, None] + n_img // 2
    cx = sx[None, :] + n_img // 2
    inside = (cy >= 0) & (cy < hc) & (cx >= 0) & (cx < wc)
    sc = jnp.where(inside, sc, -jnp.inf)
    # the 5 x 5 maximum as a 5 x 1 then a 1 x 5 one: the same values (max is exact), 8x faster
    # on XLA:CPU, where a 2-D window costs 25 compares per cell
    pooled = jax.lax.reduce_window(sc, -jnp.inf, jax.lax.max, (5, 1), (1, 1), "SAME")
    pooled = jax.lax.reduce_window(pooled, -jnp.inf, jax.lax.max, (1, 5), (1, 1), "SAME")
    peak = jnp.where(sc >= pooled, sc, -jnp.inf).reshape(-1)
    val, idx = jax.lax.top_k(peak, k)
    iy, ix = idx // fw, idx % fw
    tx = origin[0] + half + sx[ix].astype(jnp.float32) * res
    ty = origin[1] + half + sy[iy].astype(jnp.float32) * res
    return jnp.stack([tx, ty, jnp.full_like(tx, th)], -1), val


def fft_size(n: int) -> int:
    """The smallest ``2^a 3^b 5^c >= n`` (sizes the FFT handles fast)."""
    best = 1 << max(0, (int(n) - 1).bit_length())
    for a in range(best.bit_length()):
        for b in range(8):
            for c in range(6):
                v = (1 << a) * 3**b * 5**c
                if n <= v < best:
                    best = v
    return best


def corr_size(side: int, n_img: int) -> int:
    """The FFT length, along one axis, of the correlation of an ``n_img`` image (its centre
    at ``c = n_img // 2``) with a plan field of ``side`` cells that is zero outside them, for
    the shifts ``s`` that put the image's centre on the plan (``s = -c .. side - c - 1``).

    The circular correlation of length ``L`` reads the field at ``u + s (mod L)`` for image
    cells ``u = 0 .. n_img - 1``: from ``-c`` to ``side + n_img - c - 2``. It equals the
    linear one where the indices past either end land in the zero padding ``side .. L - 1``:
    ``L >= side + c`` (the negative ones wrap to ``L - c ..``) and ``L >= side + n_img - c - 1``
    (the positive ones), so ``L >= side + n_img // 2`` (rounded up by ``fft_size``), not
    ``side + n_img``: about half the padding. Shifts stored at ``side - c .. side - 1`` put the
    centre off the plan and are masked (``map_peaks``). On a plan narrower than half the
    image ``L`` may be less than ``n_img``; the transform then crops the image to ``L``, and
    the cropped cells ``u >= L >= side + c`` would read the field at ``u + s >= side``: zero."""
    return fft_size(int(side) + int(n_img) // 2)


def _coarse(pts, pok, frees, fok, fields, p: SearchParams, n_img: int):
    """Best ``peaks_per_yaw`` coarse placements per heading: ``(Y * P, 3)`` and scores."""
    res = fields.c_res
    half = n_img * res / 2
    hc, wc = fields.c_hit.shape
    # Correlation sizes: the least fast FFT lengths free of wrap-around (``corr_size``).
    fh, fw = corr_size(hc, n_img), corr_size(wc, n_img)
    npts = jnp.maximum(jnp.sum(pok), 1).astype(jnp.float32)
    nfree = jnp.maximum(jnp.sum(fok), 1).astype(jnp.float32)
    F_hit = jnp.fft.rfft2(fields.c_hit, (fh, fw)) * (1.0 / npts).astype(jnp.complex64)
    F_bad = jnp.fft.rfft2(fields.c_bad, (fh, fw)) * (p.lam / nfree).astype(jnp.complex64)
    c_origin = fields.origin  # coarse grid shares the fine origin
    yaws = jnp.deg2rad(jnp.arange(0.0, 360.0, p.yaw_step_deg))

    def one(th):
        R = jnp.asarray([[jnp.cos(th), -jnp.sin(th)], [jnp.sin(th), jnp.cos(th)]])
        img_p = splat(pts @ R.T, pok, n_img, res, half)
        img_f = splat(frees @ R.T, fok, n_img, res, half)
        # score[s] = sum_u img[u] field[u + s]; s = -(n-1) .. hc-1, stored modulo fh / fw.
        spec = F_hit * jnp.conj(jnp.fft.rfft2(img_p, (fh, fw))) - F_bad * jnp.conj(
            jnp.fft.rfft2(img_f, (fh, fw))
        )
        sc = jnp.fft.irfft2(spec, (fh, fw))
        return map_peaks(sc, th, (hc, wc), n_img, res, c_origin, p.peaks_per_yaw)

    poses, vals = jax.lax.map(one, yaws)
    return poses.reshape(-1, 3), vals.reshape(-1)


def polish(g, pts, pok, frees, fok, fields, lam, step_xy, step_yaw, n):
    """Local grid search (``(2n+1)^3`` placements) around ``g``; returns the best."""
    d = jnp.arange(-n, n + 1, dtype=jnp.float32)
    dx, dy, dt = jnp.meshgrid(d * step_xy, d * step_xy, d * step_yaw, indexing="ij")
    cand = g + jnp.stack([dx.ravel(), dy.ravel(), dt.ravel()], -1)
    sc = jax.vmap(lambda c: _score(c, pts, pok, frees, fok, fields, lam))(cand)
    i = jnp.argmax(sc)
    return cand[i], sc[i]


def refine_placement(g, pts, pok, frees, fok, fields, lam):
    """``polish`` twice: 0.12 m / 1.2 deg steps two cells out, then 0.04 m / 0.4 deg one cell
    out (reaches about 0.3 m and 3 deg from a coarse peak). Returns ``(pose, score)``."""
    g, _ = polish(g, pts, pok, frees, fok, fields, lam, 0.12, math.radians(1.2), 2)
    return polish(g, pts, pok, frees, fok, fields, lam, 0.04, math.radians(0.4), 1)


def nms(poses, vals, n, nms_xy, nms_rad):
    """Greedy suppression: the ``n`` best placements, pairwise at least (nms_xy or nms_rad)."""
    order = jnp.argsort(-vals)
    poses, vals = poses[order], vals[order]

    def body(i, keep):
        dxy, dth = se2.distance_pair(poses, poses[i])
        close = (dxy < nms_xy) & (dth < nms_rad) & (jnp.arange(len(vals)) < i) & keep
        return keep.at[i].set(keep[i] & ~jnp.any(close))

    keep = jax.lax.fori_loop(0, len(vals), body, jnp.isfinite(vals))
    sel = jnp.argsort(jnp.where(keep, -vals, jnp.inf))[:n]
    return poses[sel], jnp.where(keep[sel], vals[sel], -jnp.inf)


def search(pts, pok, frees, fok, fields: PlanFields, p: SearchParams, n_img: int):
    """Best rigid placements of a cloud in the plan.

    Args:
        pts: ``(M, 2)`` points of the accumulated path in frame ``F``, CENTRED (subtract the
            cloud centre ``c`` first; a placement ``g`` then maps ``x - c`` into B).
        pok: ``(M,)`` bool.
        frees: ``(Q, 2)`` free-space samples (ray samples and sensor positions), centred alike.
        fok: ``(Q,)`` bool.
        fields: ``PlanFields``.
        p: ``SearchParams`` (static).
        n_img: static cloud image side (cells of ``fields.c_res``), covering the cloud's extent.

    Returns:
        ``(poses (n_out, 3), scores (n_out,))``: placements of the centred cloud, best first
        (``-inf`` scores where fewer distinct placements exist).
    """
    poses, vals = _coarse(pts, pok, frees, fok, fields, p, n_img)
    poses, vals = nms(poses, vals, p.n_peaks, p.nms_xy, math.radians(p.nms_deg))
    # polish on an even subsample (the cloud is already in random order)
    sp = max(1, pts.shape[0] // p.polish_points)
    sf = max(1, frees.shape[0] // max(p.polish_points // 2, 1))
    q, qok, f, fok2 = pts[::sp], pok[::sp], frees[::sf], fok[::sf]

    poses, sc = jax.vmap(lambda g: refine_placement(g, q, qok, f, fok2, fields, p.lam))(poses)
    sc = jnp.where(jnp.isfinite(vals), sc, -jnp.inf)
    return nms(poses, sc, p.n_out, 0.5, math.radians(3.0))


def uncentre(g, c):
    """Placements ``g (n, 3)`` of a cloud centred at ``c (2,)`` (they map ``x - c`` into B)
    as motions of the uncentred cloud: rotate about ``c``, then translate (host, float64)."""
    g = np.asarray(g, np.float64).reshape(-1, 3)
    cg, sg = np.cos(g[:, 2]), np.sin(g[:, 2])
    tx = g[:, 0] - (cg * c[0] - sg * c[1])
    ty = g[:, 1] - (sg * c[0] + cg * c[1])
    return np.stack([tx, ty, g[:, 2]], 1)
