"""Dense correlative pose hypotheses: the front-end's second source of accumulator peaks.

The corner-pair Hough (``hough.py``) needs corners: two wall lines meeting inside the submap
with both arms seen. A window along a straight corridor has none, and on real 180-degree logs
with furniture and glass most detected corners are spurious, so the true pose is often not
among its peaks at all (on the benchmark's real logs the truth was within 1 m / 5 deg of some
candidate in a quarter to a half of the windows). Wall *directions* survive both: one long
wall fixes the heading up to the plan's few wall directions.

So, per submap:

1. Headings: each of the submap's ``dense_sub_dirs`` strongest, mutually non-parallel wall
   lines aligned with each of the plan's ``dense_plan_dirs`` dominant wall directions (peaks
   of a histogram of the plan's corner edge directions, host side), both ways round.
2. Translations, exhaustively per heading: the submap's points and free-space samples are
   splatted at the plan's coarse cell (``path_search``'s fields, about 0.4 m) and
   cross-correlated with the plan's wall-proximity and obstacle fields by FFT (one inverse
   transform per heading: the two correlations are summed in the frequency domain).
   The ``dense_peaks_per_yaw`` best local maxima of each heading are kept.
3. The best ``dense_n`` distinct peaks are polished by ``path_search``'s local grid search
   and handed to the prescreen with the Hough peaks: from there on both kinds are scored,
   refined and ranked by the same verification, so a dense peak becomes a candidate only
   when the scan supports it better than the corner hypotheses.

Pure array code for one submap (``pipeline.features_of`` maps it over the chunk); the plan
side (``DenseFields``) is built once per building on the host.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.frontend import path_search as ps

__all__ = ["DenseFields", "dense_fields", "plan_directions", "headings", "peaks"]

_RAY_FRACS = (0.3, 0.6, 0.85)  # free samples along each ray (as the rival search)


@dataclass(frozen=True)
class DenseFields:
    """The plan as the dense search reads it (pytree).

    Attributes:
        fields: ``path_search.PlanFields`` (fine fields for polishing, coarse for the FFT).
        f_hit, f_bad: ``(fh, fw // 2 + 1)`` complex spectra of the coarse fields at the
            correlation size (``fh, fw = path_search.corr_size`` of the field's sides and
            ``n`` = ``dense_img``).
        dirs: ``(D,)`` dominant wall directions of the plan (rad, modulo pi); dir_ok: ``(D,)``.
    """

    fields: ps.PlanFields
    f_hit: jax.Array
    f_bad: jax.Array
    dirs: jax.Array
    dir_ok: jax.Array


jax.tree_util.register_dataclass(
    DenseFields, data_fields=["fields", "f_hit", "f_bad", "dirs", "dir_ok"], meta_fields=[]
)


def plan_directions(a1, a2, valid, n: int, sep_deg: float = 15.0):
    """The ``n`` dominant wall directions of a plan from its corners' edge angles (host).

    Every valid corner contributes its two edges (angles modulo pi) to a 1-degree circular
    histogram, smoothed over +-2 degrees; peaks at least ``sep_deg`` apart, strongest first.

    Returns:
        ``(dirs (n,), ok (n,))`` float32 radians in ``[0, pi)`` and bool.
    """
    v = np.asarray(valid, bool).reshape(-1)
    ang = np.concatenate([np.asarray(a1).reshape(-1)[v], np.asarray(a2).reshape(-1)[v]])
    dirs, ok = np.zeros(n, np.float32), np.zeros(n, bool)
    if ang.size == 0:
        return dirs, ok
    deg = np.mod(np.degrees(ang), 180.0)
    h = np.bincount(np.floor(deg).astype(int) % 180, minlength=180).astype(np.float64)
    h = sum(np.roll(h, s) for s in range(-2, 3))
    for i in range(n):
        j = int(np.argmax(h))
        if h[j] <= 0:
            break
        # the peak's direction: circular mean (doubled angles) of the edges within 3 deg of it
        near = np.abs((deg - j - 0.5 + 90.0) % 180.0 - 90.0) <= 3.0
        z = np.mean(np.exp(2j * np.radians(deg[near])))
        dirs[i], ok[i] = np.mod(np.angle(z) / 2, np.pi), True
        d = np.abs((np.arange(180) - j + 90) % 180 - 90)
        h[d < sep_deg] = 0.0
    return dirs, ok


def dense_fields(rasters, a1, a2, valid, p) -> DenseFields:
    """``DenseFields`` of a (padded) ``Rasters`` and the plan's corner edges (host)."""
    sp = ps.SearchParams(coarse_res=p.dense_res)
    f = ps.plan_fields(rasters, sp)
    hc, wc = f.c_hit.shape
    size = (ps.corr_size(hc, p.dense_img), ps.corr_size(wc, p.dense_img))
    dirs, ok = plan_directions(a1, a2, valid, p.dense_plan_dirs)
    return DenseFields(
        fields=jax.tree.map(jnp.asarray, f),
        f_hit=jnp.asarray(np.fft.rfft2(f.c_hit, size).astype(np.complex64)),
        f_bad=jnp.asarray(np.fft.rfft2(f.c_bad, size).astype(np.complex64)),
        dirs=jnp.asarray(dirs),
        dir_ok=jnp.asarray(ok),
    )


def headings(lines, dense: DenseFields, p):
    """Candidate headings of one submap from its wall lines (``features.detect_lines``).

    Returns:
        ``(yaw (S * D * 2,), ok)``: each of the ``dense_sub_dirs`` strongest valid lines that
        is at least 20 degrees off the stronger ones, aligned with each plan direction, both
        ways round.
    """
    u, valid = lines["u"], lines["valid"]
    phi = jnp.mod(jnp.arctan2(u[:, 1], u[:, 0]), jnp.pi)
    n = phi.shape[0]
    # greedy: a line is a new direction when no stronger accepted line is within 20 deg
    d = jnp.abs(jnp.mod(phi[:, None] - phi[None, :] + jnp.pi / 2, jnp.pi) - jnp.pi / 2)

    def take(acc, i):
        near = jnp.any(acc & (d[i] < math.radians(20.0)))
        new = valid[i] & ~near
        return acc.at[i].set(new), new

    acc, _ = jax.lax.scan(take, jnp.zeros(n, bool), jnp.arange(n))
    order = jnp.argsort(~acc, stable=True)[: p.dense_sub_dirs]
    s_phi, s_ok = phi[order], acc[order]
    yaw = dense.dirs[None, :] - s_phi[:, None]  # (S, D)
    ok = s_ok[:, None] & dense.dir_ok[None, :]
    yaw = jnp.stack([yaw, yaw + jnp.pi], -1).reshape(-1)
    ok = jnp.stack([ok, ok], -1).reshape(-1)
    # half-open [-pi, pi) here, not se2.wrap: a heading of exactly pi (a wall direction plus
    # pi) keeps coming out as -pi; atan2 gives +pi there, which changes which candidates
    # survive (with se2.wrap here two baseline runs of the study decide otherwise)
    yaw = jnp.mod(yaw + jnp.pi, 2 * jnp.pi) - jnp.pi
    # A heading within 3 deg of an earlier valid one is a duplicate (perpendicular walls of a
    # rectilinear plan give each heading several times); ``_coarse`` skips it.
    dd = jnp.abs(jnp.mod(yaw[:, None] - yaw[None, :] + jnp.pi, 2 * jnp.pi) - jnp.pi)
    m = yaw.shape[0]
    earlier = jnp.arange(m)[None, :] < jnp.arange(m)[:, None]
    dup = jnp.any(earlier & ok[None, :] & (dd < math.radians(3.0)), axis=1)
    return yaw, ok & ~dup


def _free(pts, org, ok):
    fr = jnp.asarray(_RAY_FRACS, pts.dtype)[:, None, None]
    q = (org[None] + fr * (pts - org)[None]).reshape(-1, 2)
    return jnp.concatenate([q, org]), jnp.concatenate([jnp.tile(ok, len(_RAY_FRACS)), ok])


def _coarse(pts, pok, frees, fok, dense: DenseFields, yaws, yok, p):
    """Best ``dense_peaks_per_yaw`` coarse placements of the centred cloud per heading."""
    f = dense.fields
    res, n = f.c_res, p.dense_img
    half = n * res / 2
    plan_shape = f.c_hit.shape
    size = (ps.corr_size(plan_shape[0], n), ps.corr_size(plan_shape[1], n))  # dense_fields'
    npts = jnp.maximum(jnp.sum(pok), 1).astype(jnp.float32)
    nfree = jnp.maximum(jnp.sum(fok), 1).astype(jnp.float32)
    k = p.dense_peaks_per_yaw

    def heading(th):
        R = jnp.asarray([[jnp.cos(th), -jnp.sin(th)], [jnp.sin(th), jnp.cos(th)]])
        img_p = ps.splat(pts @ R.T, pok, n, res, half) / npts
        img_f = ps.splat(frees @ R.T, fok, n, res, half) * (p.dense_lam / nfree)
        # hit minus penalty, summed in the frequency domain: one inverse transform
        spec = dense.f_hit * jnp.conj(jnp.fft.rfft2(img_p, size))
        spec = spec - dense.f_bad * jnp.conj(jnp.fft.rfft2(img_f, size))
        g, v = ps.map_peaks(jnp.fft.irfft2(spec, size), th, plan_shape, n, res, f.origin, k)
        return g.astype(jnp.float32), v.astype(jnp.float32)

    def skip(th):
        return jnp.zeros((k, 3), jnp.float32), jnp.full((k,), -jnp.inf, jnp.float32)

    # sequential over headings so that a skipped (invalid or duplicate) one costs nothing
    poses, vals = jax.lax.map(lambda a: jax.lax.cond(a[1], heading, skip, a[0]), (yaws, yok))
    vals = jnp.where(yok[:, None], vals, -jnp.inf)
    return poses.reshape(-1, 3), vals.reshape(-1)


def peaks(pts, org, ok, lines, dense: DenseFields, p):
    """Dense pose hypotheses of one submap.

    Args:
        pts, org: ``(n, 2)`` subsampled submap points and their sensor origins; ok: ``(n,)``.
        lines: ``features.detect_lines`` of the same points.
        dense: the building's ``DenseFields``; p: ``FrontendParams``.

    Returns:
        ``(poses (dense_n, 3), ok (dense_n,))``: submap poses ``^B T_S``, best coarse first.
    """
    cnt = jnp.maximum(jnp.sum(ok), 1).astype(jnp.float32)
    c = jnp.sum(jnp.where(ok[:, None], pts, 0.0), 0) / cnt
    q = jnp.where(ok[:, None], pts - c, 0.0)
    o = jnp.where(ok[:, None], org - c, 0.0)
    frees, fok = _free(q, o, ok)
    yaws, yok = headings(lines, dense, p)
    g, val = _coarse(q, ok, frees, fok, dense, yaws, yok, p)
    g, val = ps.nms(g, val, p.dense_n, 1.0, math.radians(6.0))
    sp = max(1, q.shape[0] // p.dense_polish_points)
    sf = max(1, frees.shape[0] // p.dense_polish_points)
    qq, qok, ff, ffok = q[::sp], ok[::sp], frees[::sf], fok[::sf]
    g, _ = jax.vmap(
        lambda gi: ps.refine_placement(gi, qq, qok, ff, ffok, dense.fields, p.dense_lam)
    )(g)
    good = jnp.isfinite(val)
    # placements of the centred cloud -> poses of the submap frame
    cg, sg = jnp.cos(g[:, 2]), jnp.sin(g[:, 2])
    pose = jnp.stack(
        [g[:, 0] - (cg * c[0] - sg * c[1]), g[:, 1] - (sg * c[0] + cg * c[1]), g[:, 2]], -1
    )
    return jnp.where(good[:, None], pose, 0.0), good
