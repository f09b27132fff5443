"""Pose Hough transform: corner correspondences vote for ``Y = ^B T_S`` in (x, y, yaw).

Every (submap corner, plan corner) pair with the same opening angle (within
``corner_angle_tol_deg``) and compatible kind gives one closed-form pose: the rotation that
carries the submap's edge directions onto the plan's (circular mean of the two edge offsets) and
the translation that then carries the corner onto the corner.

The (x, y, yaw) accumulator (``cell`` x ``cell`` x ``yaw_bin_deg``, STSL's 0.15 m x 0.15 m x
1 deg) is never built densely: a 30 x 20 m floor would need ~10^7 cells per submap, almost all
empty. It is evaluated at the votes themselves (see ``vote``): the smoothed count of a vote is the
vote weight in the ``3 x 3 x 3`` cell window centred on it, non-maximum suppression keeps votes
that no heavier vote beats within ``nms_xy`` / ``nms_deg``, and the top ``n_prescreen`` survivors,
each placed at the mean of the votes in its window, become candidates.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from mfcl_jax import se2

__all__ = ["corner_votes", "vote"]


def _wrap(a):
    """Wraps an angle in ``[-3 pi, 3 pi]`` (a sum or difference of angles in ``[-pi, pi]``,
    as every angle here is) to ``[-pi, pi]`` by one shift of ``2 pi``: exact, and no
    transcendental (``se2.wrap`` costs an atan2, a sin and a cos per angle)."""
    return jnp.where(a > jnp.pi, a - 2 * jnp.pi, jnp.where(a < -jnp.pi, a + 2 * jnp.pi, a))


def corner_votes(sub, plan, p):
    """Closed-form poses for all corner pairs.

    Args:
        sub: submap corners (``features.detect_corners``), ``C_s`` entries.
        plan: plan corners ``(pos, a1, a2, kind, valid)`` with ``C_f`` entries; all edge
            angles in ``[-pi, pi]``.
        p: ``FrontendParams``.

    Returns:
        ``(poses (C_s * C_f, 3), weights (C_s * C_f,))``; incompatible pairs weigh 0.
    """
    fpos, fa1, fa2, fkind, fvalid = plan
    open_s = _wrap(sub["a2"] - sub["a1"])
    open_f = _wrap(fa2 - fa1)
    ok = sub["valid"][:, None] & fvalid[None, :]
    ok &= jnp.abs(_wrap(open_s[:, None] - open_f[None, :])) <= math.radians(p.corner_angle_tol_deg)
    ok &= (sub["kind"][:, None] == 0) | (sub["kind"][:, None] == fkind[None, :])
    r1 = _wrap(fa1[None, :] - sub["a1"][:, None])
    r2 = _wrap(fa2[None, :] - sub["a2"][:, None])
    theta = _wrap(r1 + 0.5 * _wrap(r2 - r1))
    spos = jnp.broadcast_to(sub["pos"][:, None, :], theta.shape + (2,))
    t = fpos[None, :, :] - se2.rotate(theta, spos)
    poses = jnp.concatenate([t, theta[..., None]], -1).reshape(-1, 3)
    # When the pairs overflow the vote budget, the heaviest are kept: every submap corner keeps
    # its pairs with the most salient plan corners (plan corners come most salient first,
    # ``Floorplan.corners``; submap corners strongest first), rank by rank across corners.
    cs, cf = ok.shape
    rank = (jnp.cumsum(ok, axis=1) - 1).astype(jnp.float32)  # among the corner's matches
    tie = jnp.arange(cs, dtype=jnp.float32)[:, None] / cs
    w = jnp.where(ok, 1.0 / (1.0 + rank + tie), 0.0)
    return poses, w.reshape(-1).astype(jnp.float32)


def _peaks(v, wt, p, n_out: int):
    """Accumulator peaks among the ``m`` votes ``v (m, 3)`` (heaviest first, weights ``wt``,
    0 past the valid ones): ``(pose (n_out, 3), votes (n_out,))``, zero-padded past ``m``."""
    m = v.shape[0]
    good = wt > 0
    half_cell, half_yaw = 1.5 * p.cell, math.radians(1.5 * p.yaw_bin_deg)
    # Pairwise offsets, m x m each. Headings in [-pi, pi] differ by at most 2 pi, so the
    # wrapped difference is min(|d|, 2 pi - |d|): no floating-point modulo per pair.
    dx = jnp.abs(v[:, None, 0] - v[None, :, 0])
    dy = jnp.abs(v[:, None, 1] - v[None, :, 1])
    dth = jnp.abs(v[:, None, 2] - v[None, :, 2])
    dth = jnp.minimum(dth, 2 * jnp.pi - dth)
    # XLA:CPU does not fuse a reduction with its operand: the m x m masks are reduced by
    # matrix-vector products (vectorised), each mask built in one elementwise pass.
    win = ((dx <= half_cell) & (dy <= half_cell) & (dth <= half_yaw)).astype(jnp.float32)
    count = win @ wt
    ar = jnp.arange(m)
    heavier = (count[None, :] > count[:, None]) | (
        (count[None, :] == count[:, None]) & (ar[None, :] < ar[:, None])
    )
    nms = (dx * dx + dy * dy <= p.nms_xy**2) & (dth <= math.radians(p.nms_deg))
    beaten = (nms & heavier & good[None, :]).astype(jnp.float32) @ jnp.ones(m, jnp.float32)
    peak = good & (beaten == 0)
    top, sel = jax.lax.top_k(jnp.where(peak, count, 0.0), min(n_out, m))
    # Mean position/heading of each peak's window, referenced to the peak vote (no wrap issues).
    ref = v[sel]
    ww = win[sel] * wt[None, :]  # (n_out, m)
    tot = jnp.maximum(jnp.sum(ww, -1), 1e-9)
    xy = (ww @ v[:, :2]) / tot[:, None]
    dyaw = _wrap(v[None, :, 2] - ref[:, None, 2])
    yaw = _wrap(ref[:, 2] + jnp.sum(ww * dyaw, -1) / tot)
    pose = jnp.concatenate([xy, yaw[:, None]], -1)
    pad = n_out - top.shape[0]
    return jnp.pad(pose, ((0, pad), (0, 0))), jnp.pad(top, (0, pad))


def vote(poses, w, p, n_out: int | None = None):
    """Accumulate votes and extract the top ``p.n_hough`` pose peaks.

    The 3D accumulator is evaluated only where votes are (it is zero elsewhere): the valid
    votes (at most ``p.max_votes``, heaviest first) are compared pairwise, each vote's
    smoothed count is the weight inside its ``3 x 3 x 3`` cell window (``+-1.5 cell``,
    ``+-1.5 yaw_bin_deg``), and a vote is a peak when no heavier vote (ties: lower index)
    lies within the NMS window. Cost is ``O(m^2)``, independent of floor area, with ``m`` the
    smallest of ``max_votes / 16``, ``/ 8``, ``/ 4``, ``/ 2`` and ``max_votes`` that holds
    every valid vote (a ``lax.switch``: the invalid votes weigh nothing, so the peaks are the same
    for any ``m`` that holds the valid ones; most submaps cast about a hundred votes. Under
    ``vmap`` every branch runs, so the pipeline calls this per submap).

    Args:
        poses: ``(V, 3)`` vote poses, headings in ``[-pi, pi]`` (as ``corner_votes`` gives);
            ``w`` ``(V,)`` weights (0 = no vote).
        p: ``FrontendParams``.
        n_out: static number of peaks returned (default ``p.n_hough``).

    Returns:
        ``(pose (J_h, 3), votes (J_h,), valid (J_h,), n_votes, overflow)``, strongest first;
        each pose is the mean of the votes in its window (padding: zero pose, zero votes).
    """
    M = min(p.max_votes, poses.shape[0])
    n_out = min(n_out or p.n_hough, M)
    n_votes = jnp.sum(w > 0)
    wt, idx = jax.lax.top_k(w, M)  # the weights rank the pairs for the budget ...
    v = poses[idx]
    wt = (wt > 0).astype(jnp.float32)  # ... and every kept pair casts one vote
    sizes = sorted({max(1, M // 16), max(1, M // 8), max(1, M // 4), max(1, M // 2), M})
    # top_k lists equal weights by index, so the m heaviest are a prefix of the M heaviest.
    branches = [lambda v, wt, m=m: _peaks(v[:m], wt[:m], p, n_out) for m in sizes]
    branch = jnp.sum(n_votes > jnp.asarray(sizes[:-1]))
    pose, top = jax.lax.switch(branch, branches, v, wt)
    return pose, top, top > 0, n_votes, n_votes > M
