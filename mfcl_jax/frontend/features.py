"""Features shared by a LiDAR submap and the floor plan: wall lines and wall corners.

Submap side (pure JAX, one submap, static shapes; ``vmap`` it): a (rho, theta) line Hough over a
strided subsample of the submap's points, ``L`` lines picked by iterative non-maximum
suppression and refitted (total least squares) on their inliers; the free side of each line from
the sensor origins of its inliers; corners from pairs of non-parallel lines whose *arms* (inlier
support within ``[arm_min, arm_max]`` of the intersection, on one side) both exist.

A corner is ``(position, a1, a2, kind)``: ``a1``/``a2`` are the angles of its two edges pointing
away from the corner, ordered so that ``a2 - a1`` (wrapped) lies in ``(0, pi)``; ``kind`` is +1
when free space fills the wedge between the edges (a room's inner corner), -1 when the wedge is
solid (a protruding corner, door jamb), 0 when unknown. A rigid motion preserves all of this,
so a (submap corner, plan corner) pair of equal opening angle and compatible kind fixes one
SE(2) pose in closed form (``hough.py``).

Floor-plan side (host, NumPy + shapely, once per building): ``Floorplan.corners`` reordered the
same way, classified by testing the wedge's bisector against the wall solid, and padded.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import shapely

from mfcl_jax import se2
from mfcl_jax.frontend.materialize import materialize
from mfcl_jax.se2 import wrap_host

__all__ = ["compact", "subsample", "detect_lines", "detect_corners", "floorplan_corners"]


def compact(points, origins, mask):
    """Moves the valid points (finite, masked in) to the front, scan order kept.

    Returns:
        ``(points, origins, mask)`` of the same shapes; invalid slots hold zeros.
    """
    valid = mask & jnp.all(jnp.isfinite(points), -1) & jnp.all(jnp.isfinite(origins), -1)
    # The valid indices in scan order (a prefix sum and a scatter, not a sort of P keys).
    order = jnp.nonzero(valid, size=valid.shape[0], fill_value=0)[0]
    ok = jnp.arange(valid.shape[0]) < jnp.sum(valid)
    pts = jnp.where(ok[:, None], jnp.nan_to_num(points[order]), 0.0)
    org = jnp.where(ok[:, None], jnp.nan_to_num(origins[order]), 0.0)
    return pts, org, ok


def subsample(points, origins, mask, n: int, compacted: bool = False):
    """Deterministic strided subsample of the valid points (scan order kept).

    Args:
        points: ``(P, 2)`` submap points; non-finite entries are treated as invalid.
        origins: ``(P, 2)`` sensor origins of the points.
        mask: ``(P,)`` bool.
        n: static output size.
        compacted: the input already went through ``compact`` (skips the compaction).

    Returns:
        ``(pts (n, 2), org (n, 2), ok (n,), n_valid)``; invalid slots hold zeros.
    """
    if not compacted:
        points, origins, mask = compact(points, origins, mask)
    n_valid = jnp.sum(mask)
    stride = jnp.maximum(n_valid.astype(jnp.float32) / n, 1.0)
    idx = jnp.floor(jnp.arange(n, dtype=jnp.float32) * stride).astype(jnp.int32)
    ok = idx < n_valid
    idx = jnp.clip(idx, 0, points.shape[0] - 1)
    pts = jnp.where(ok[:, None], points[idx], 0.0)
    org = jnp.where(ok[:, None], origins[idx], 0.0)
    # Later loops read the subsample once per line, corner or pose: compute it once.
    px, py, ox, oy, ok = materialize(pts[:, 0], pts[:, 1], org[:, 0], org[:, 1], ok)
    return jnp.stack([px, py], -1), jnp.stack([ox, oy], -1), ok, n_valid


def _line_peaks(q, ok, p, n_peaks):
    """Top ``n_peaks`` (theta, rho) Hough peaks of centred points ``q``: ``(theta, rho, votes)``."""
    T = p.line_theta_bins
    R = int(math.ceil(2 * p.rho_max / p.line_rho_res))
    th = jnp.arange(T, dtype=jnp.float32) * (jnp.pi / T)
    rho = q[:, 0:1] * jnp.cos(th) + q[:, 1:2] * jnp.sin(th)  # (n, T)
    ri = jnp.floor((rho + p.rho_max) / p.line_rho_res).astype(jnp.int32)
    good = ok[:, None] & (ri >= 0) & (ri < R)
    flat = jnp.where(good, jnp.arange(T)[None, :] * R + ri, T * R)  # T * R: a dump slot
    acc = jnp.zeros(T * R + 1).at[flat.ravel()].add(1.0, mode="promise_in_bounds")
    acc = acc[:-1].reshape(T, R)
    # Noise spreads a wall over neighbouring rho bins: a 3-bin box along rho gathers it.
    acc = acc + jnp.pad(acc[:, 1:], ((0, 0), (0, 1))) + jnp.pad(acc[:, :-1], ((0, 0), (1, 0)))
    wt = max(1, round(p.line_nms_deg * T / 180.0))
    wr = max(1, round(p.line_nms_rho / p.line_rho_res))
    # Local maxima in a (2 wt + 1) x (2 wr + 1) window; theta wraps at pi with rho negated,
    # so the accumulator is padded with its flipped ends. A tiny ramp breaks plateaus. The
    # window max is separable: one pass along theta, one along rho (4x fewer comparisons).
    acc = acc + 1e-4 * jnp.arange(T * R, dtype=jnp.float32).reshape(T, R) / (T * R)
    ext = jnp.concatenate([acc[-wt:, ::-1], acc, acc[:wt, ::-1]], 0)
    mx = jax.lax.reduce_window(ext, -jnp.inf, jax.lax.max, (2 * wt + 1, 1), (1, 1), "VALID")
    mx = jax.lax.reduce_window(
        mx, -jnp.inf, jax.lax.max, (1, 2 * wr + 1), (1, 1), ((0, 0), (wr, wr))
    )
    peak = (acc >= mx) & (acc >= 1.0)
    v, k = jax.lax.top_k(jnp.where(peak, acc, 0.0).ravel(), n_peaks)
    t, r = k // R, k % R
    t, r = t.astype(jnp.float32), r.astype(jnp.float32)
    return t * (jnp.pi / T), (r + 0.5) * p.line_rho_res - p.rho_max, v


def _moments(qx, qy, w):
    """Weighted centroid and total-least-squares direction angle of points ``(qx, qy)`` under
    weights ``w``, reduced over axis 0 (the points). Returns ``(mx, my, angle)``."""
    k = jnp.maximum(jnp.sum(w, 0), 1.0)
    mx, my = jnp.sum(w * qx, 0) / k, jnp.sum(w * qy, 0) / k
    dx, dy = qx - mx, qy - my
    sxx, syy, sxy = jnp.sum(w * dx * dx, 0), jnp.sum(w * dy * dy, 0), jnp.sum(w * dx * dy, 0)
    return mx, my, 0.5 * jnp.arctan2(2 * sxy, sxx - syy)


def _refit(q, ok, theta, rho, band):
    """Total-least-squares refit of lines on their inliers. Returns ``(u, m, inl)``."""
    qx, qy = q[:, 0:1], q[:, 1:2]  # (n, 1): lines along the last axis
    d = qx * jnp.cos(theta) + qy * jnp.sin(theta) - rho  # (n, L)
    inl = (jnp.abs(d) <= band) & ok[:, None]
    mx, my, ang = _moments(qx, qy, inl.astype(jnp.float32))
    u = jnp.stack([jnp.cos(ang), jnp.sin(ang)], -1)
    return u, jnp.stack([mx, my], -1), inl


def detect_lines(pts, org, ok, p):
    """Wall lines of one (subsampled) submap.

    Hough peaks (``2 L`` of them, NMS) are refitted and then accepted greedily, strongest
    first, each claiming its inliers: a peak whose points were already claimed (the
    off-angle ghosts every long dense wall leaves in a Hough accumulator) is dropped.

    Args:
        pts: ``(n, 2)`` points in the submap frame; ``org`` their sensor origins; ``ok`` mask.
        p: ``FrontendParams``.

    Returns:
        dict with ``u (L, 2)`` unit directions, ``m (L, 2)`` centroids (submap frame),
        ``free (L, 2)`` unit normal towards the sensor side (zero when undecided),
        ``inl (n, L)`` inlier masks, ``count (L,)``, ``valid (L,)``, plus the centring
        offset ``q_off`` and centred points ``q``.
    """
    cnt = jnp.maximum(jnp.sum(ok).astype(jnp.float32), 1.0)
    c = jnp.sum(jnp.where(ok[:, None], pts, 0.0), 0) / cnt
    q = pts - c
    qx, qy = q[:, 0], q[:, 1]
    theta, rho, votes = _line_peaks(q, ok, p, 2 * p.n_lines)
    u, m, inl = _refit(q, ok, theta, rho, 1.5 * p.inlier_band)
    order = jnp.argsort(-jnp.sum(inl, 0), stable=True)
    u, m = u[order], m[order]
    min_pts = jnp.maximum(float(p.min_line_pts), p.min_line_frac * jnp.sum(ok).astype(jnp.float32))

    def accept(claimed, line):
        uu, mm = line
        mx, my, nx, ny = mm[0], mm[1], -uu[1], uu[0]
        free_pts = ok & ~claimed
        for band in (1.5 * p.inlier_band, p.inlier_band):
            inl = (jnp.abs((qx - mx) * nx + (qy - my) * ny) <= band) & free_pts
            mx, my, ang = _moments(qx, qy, inl.astype(jnp.float32))
            nx, ny = -jnp.sin(ang), jnp.cos(ang)
        inl = (jnp.abs((qx - mx) * nx + (qy - my) * ny) <= p.inlier_band) & free_pts
        count = jnp.sum(inl).astype(jnp.float32)
        valid = count >= min_pts
        line = (jnp.stack([ny, -nx]), jnp.stack([mx, my]), inl, count, valid)
        return claimed | (inl & valid), line

    _, (u, m, inl, count, valid) = jax.lax.scan(accept, jnp.zeros_like(ok), (u, m))
    keep = jnp.argsort(~valid, stable=True)[: p.n_lines]
    u, m, inl, count, valid = u[keep], m[keep], inl[keep].T, count[keep], valid[keep]
    nrm_x, nrm_y = -u[:, 1], u[:, 0]
    # Free side: where the sensor was when it saw the inliers.
    ray_x, ray_y = (org - pts)[:, 0:1], (org - pts)[:, 1:2]
    side = jnp.sign(ray_x * nrm_x + ray_y * nrm_y)  # (n, L)
    f = jnp.sum(jnp.where(inl, side, 0.0), 0) / jnp.maximum(count, 1.0)
    nrm = jnp.stack([nrm_x, nrm_y], -1)
    free = jnp.where((jnp.abs(f) >= 0.5)[:, None], jnp.sign(f)[:, None] * nrm, 0.0)
    return dict(u=u, m=m + c, q_off=c, free=free, inl=inl, count=count, valid=valid, q=q)


def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


def detect_corners(lines, ok, p):
    """Corners from pairs of lines (see module docstring).

    Returns:
        dict with ``pos (C, 2)``, ``a1 (C,)``, ``a2 (C,)``, ``kind (C,)`` int32, ``weight (C,)``,
        ``valid (C,)`` for ``C = p.n_corners`` (strongest first).
    """
    L = p.n_lines
    ia, ib = np.triu_indices(L, 1)
    u, m, q, inl = lines["u"], lines["m"] - lines["q_off"], lines["q"], lines["inl"]
    uax, uay, ubx, uby = u[ia, 0], u[ia, 1], u[ib, 0], u[ib, 1]
    cr = _cross(uax, uay, ubx, uby)
    pair_ok = lines["valid"][ia] & lines["valid"][ib]
    pair_ok &= jnp.abs(cr) >= math.sin(math.radians(p.corner_min_angle_deg))
    safe = jnp.where(jnp.abs(cr) > 1e-6, cr, 1.0)
    dmb = m[ib] - m[ia]
    s = _cross(dmb[:, 0], dmb[:, 1], ubx, uby) / safe
    xx, xy = m[ia, 0] + s * uax, m[ia, 1] + s * uay  # (K,) centred frame
    pair_ok &= (jnp.abs(xx) <= p.rho_max) & (jnp.abs(xy) <= p.rho_max)
    qx, qy = q[None, :, 0], q[None, :, 1]
    inl_t = inl.T & ok[None]  # (L, n)

    def arms(ux, uy, idx):
        """Inliers of line ``idx`` ``(K,)`` on either side of the corner along ``(ux, uy)``."""
        tp = (qx - xx[:, None]) * ux[:, None] + (qy - xy[:, None]) * uy[:, None]  # (K, n)
        w = inl_t[idx]
        plus = jnp.sum((w & (tp > p.arm_min) & (tp < p.arm_max)).astype(jnp.float32), -1)
        minus = jnp.sum((w & (tp < -p.arm_min) & (tp > -p.arm_max)).astype(jnp.float32), -1)
        return plus, minus

    pa, na = arms(uax, uay, ia)
    pb, nb = arms(ubx, uby, ib)
    fa, fb = lines["free"][ia], lines["free"][ib]
    out = []
    for sa, ca in ((1.0, pa), (-1.0, na)):
        for sb, cb in ((1.0, pb), (-1.0, nb)):
            e1x, e1y, e2x, e2y = sa * uax, sa * uay, sb * ubx, sb * uby
            swap = _cross(e1x, e1y, e2x, e2y) < 0
            e1x, e2x = jnp.where(swap, e2x, e1x), jnp.where(swap, e1x, e2x)
            e1y, e2y = jnp.where(swap, e2y, e1y), jnp.where(swap, e1y, e2y)
            n1, n2 = jnp.where(swap[:, None], fb, fa), jnp.where(swap[:, None], fa, fb)
            d12 = n1[:, 0] * e2x + n1[:, 1] * e2y
            d21 = n2[:, 0] * e1x + n2[:, 1] * e1y
            known = (jnp.abs(n1[:, 0]) + jnp.abs(n1[:, 1]) > 0) & (
                jnp.abs(n2[:, 0]) + jnp.abs(n2[:, 1]) > 0
            )
            inside, outside = (d12 > 0) & (d21 > 0), (d12 < 0) & (d21 < 0)
            kind = jnp.where(known, jnp.where(inside, 1, -1), 0).astype(jnp.int32)
            w = jnp.minimum(ca, cb)
            good = pair_ok & (w >= p.min_arm_pts) & (~known | inside | outside)
            a1 = jnp.arctan2(e1y, e1x)
            a2 = jnp.arctan2(e2y, e2x)
            out.append((a1, a2, kind, jnp.where(good, w, -1.0)))
    a1, a2, kind, wt = (jnp.concatenate(z, 0) for z in zip(*out, strict=True))
    top, idx = jax.lax.top_k(wt, p.n_corners)
    x = jnp.stack([xx, xy], -1)
    return dict(
        pos=x[idx % x.shape[0]] + lines["q_off"],
        a1=a1[idx],
        a2=a2[idx],
        kind=kind[idx],
        weight=jnp.maximum(top, 0.0),
        valid=top > 0,
    )


def floorplan_corners(fp, capacity: int | None = None, probe: float = 0.03):
    """Host-side plan corners in the same convention as ``detect_corners``, padded.

    Args:
        fp: ``Floorplan``.
        capacity: padded size (default: next multiple of 64, at least 64).
        probe: distance (m) along the wedge bisector used to tell solid from free.

    Returns:
        ``(pos (C, 2) f32, a1 (C,) f32, a2 (C,) f32, kind (C,) i32, valid (C,) bool)``.
    """
    pts, dirs = fp.corners
    a, b = dirs[:, 0], dirs[:, 1]
    gap = wrap_host(b - a)
    swap = gap < 0
    a1, a2 = np.where(swap, b, a), np.where(swap, a, b)
    bis = a1 + np.abs(gap) / 2
    probe_xy = pts + probe * np.stack([np.cos(bis), np.sin(bis)], -1)
    solid = shapely.contains_xy(fp.wall_solid, probe_xy[:, 0], probe_xy[:, 1]) if len(pts) else []
    kind = np.where(solid, -1, 1).astype(np.int32)
    n = len(pts)
    cap = capacity or max(64, -(-n // 64) * 64)
    if n > cap:
        raise ValueError(f"floorplan_corners: {fp.source}: {n} corners exceed capacity {cap}")

    def pad(v, dtype, fill=0):
        out = np.full((cap, *np.shape(v)[1:]), fill, dtype)
        out[:n] = v
        return out

    return (
        pad(pts, np.float32),
        pad(np.asarray(se2.wrap(a1)), np.float32),
        pad(np.asarray(se2.wrap(a2)), np.float32),
        pad(kind, np.int32),
        pad(np.ones(n, bool), bool, False),
    )
