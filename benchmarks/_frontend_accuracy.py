"""The accuracy metrics of ``benchmarks/frontend.py`` (hits, recall@J, top-1, ties, aliases,
refinement errors; the definitions are in its docstring) and the diagnosis printed for the
submaps without a hit."""

from __future__ import annotations

import numpy as np

from mfcl_jax import se2
from mfcl_jax.frontend import features, hough

HIT_XY, HIT_DEG = 0.5, 2.0
TIE = 1e-3  # score difference under which two candidates are tied


def metrics(c, dbg, Y) -> dict:
    """Accuracy metrics of one (scene, d_s) from ``register_debug`` outputs (NumPy)."""
    n = len(Y)
    dxy, dth = (np.asarray(a) for a in se2.distance_pair(c.pose, Y[:, None]))
    hit = (dxy < HIT_XY) & (dth < np.radians(HIT_DEG)) & c.mask
    found = hit.any(1)
    rank = np.where(found, hit.argmax(1), -1)
    wrong = ~hit[:, 0] & c.mask[:, 0]
    tied = c.mask & (c.score >= c.score[:, :1] - TIE)
    d_top = np.asarray(se2.distance_pair(c.pose, c.pose[:, :1])[0])
    tie = (tied & (d_top >= HIT_XY)).any(1)
    d_alias = dxy[:, 0][wrong]
    walls = dbg["walls"].astype(bool)
    # Refinement: same candidate before and after.
    d0, t0 = (np.asarray(a) for a in se2.distance_pair(dbg["pose0"], Y[:, None]))
    d1, t1 = (np.asarray(a) for a in se2.distance_pair(dbg["refined"], Y[:, None]))
    k = np.argmin(np.where(dbg["ok0"], d0 + np.degrees(t0) * 0.1, np.inf), 1)
    r = np.arange(n)
    near = d0[r, k] < HIT_XY
    e0, e1 = d0[r, k][near], d1[r, k][near]
    a0, a1 = np.degrees(t0[r, k][near]), np.degrees(t1[r, k][near])
    moved = np.any(dbg["refined"] != dbg["pose0"], -1) & dbg["ok0"]
    q = lambda a, pct: float(np.percentile(a, pct)) if len(a) else np.nan  # noqa: E731
    bay, room = (d_alias >= 5.5) & (d_alias < 9), (d_alias >= 12.5) & (d_alias < 16.5)
    binned = (d_alias < 3) | bay | room
    return (
        dict(
            n_submaps=n,
            recall_at_J=found.mean(),
            top1=hit[:, 0].mean(),
            top1_tied=(hit & tied).any(1).mean(),
            tie_share=tie.mean(),
            share_2walls=walls.mean(),
            top1_2walls=hit[walls, 0].mean() if walls.any() else np.nan,
            share_corner=(dbg["n_corners"] >= 1).mean(),
            alias_share=wrong.mean(),
            alias_lt3m=(d_alias < 3).sum() / n,
            alias_5to9m=bay.sum() / n,
            alias_12to17m=room.sum() / n,
            alias_other=wrong.mean() - binned.sum() / n,
            alias_median_m=float(np.median(d_alias)) if len(d_alias) else np.nan,
            median_rank=float(np.median(rank[found])) if found.any() else np.nan,
            max_rank=int(rank.max()),
            empty=int((~c.mask.any(1)).sum()),
            refine_accepted=moved.sum() / max(dbg["ok0"].sum(), 1),
            err_before_m=q(e0, 50),
            err_before_p90_m=q(e0, 90),
            err_after_m=q(e1, 50),
            err_after_p90_m=q(e1, 90),
            err_before_deg=q(a0, 50),
            err_before_p90_deg=q(a0, 90),
            err_after_deg=q(a1, 50),
            err_after_p90_deg=q(a1, 90),
        ),
        found,
        dxy[:, 0],
        np.degrees(dth[:, 0]),
    )


def diagnose(b, Y, feats, p, rows):
    """Prints, for missed submaps: lines, corners, votes, the vote nearest the truth."""
    for i in rows:
        pts, org, ok, _ = features.subsample(b.points[i], b.origins[i], b.mask[i], p.hough_points)
        lines = features.detect_lines(pts, org, ok, p)
        corners = features.detect_corners(lines, ok, p)
        votes, w = hough.corner_votes(corners, feats.plan_corners, p)
        dxy, dth = (np.asarray(a) for a in se2.distance_pair(votes, np.float32(Y[i])))
        v = np.asarray(w) > 0
        j = np.argmin(np.where(v, dxy + 0.2 * np.degrees(dth), np.inf))
        print(
            f"    miss row {i}: {int(b.mask[i].sum())} pts, {int(lines['valid'].sum())} lines, "
            f"{int(corners['valid'].sum())} corners, {int(v.sum())} votes, nearest vote "
            f"{dxy[j]:.2f} m / {np.degrees(dth[j]):.1f} deg",
            flush=True,
        )
