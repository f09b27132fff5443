"""The per-submap front-end pipeline, in two halves batched differently.

``features_of`` (compact -> subsample -> line Hough -> corners -> corner-pair pose votes ->
accumulator peaks, plus the dense correlative peaks of ``dense.py``) runs submap after
submap (``lax.map``): its scatter, window maxima, pairwise vote tables and correlation
images are each one submap's few hundred kilobytes, cache-resident, where a chunk-wide batch
streams tens of megabytes through memory (3x slower on XLA:CPU).
``candidates_of`` (prescreen -> full score -> refinement -> re-score -> dedupe) is
``vmap``-ped over the chunk: its loops are per-pose field lookups, and batching amortises
the per-step cost of the refinement loop over the chunk.

``STAGES`` names the steps; ``run(..., stop=name)`` cuts the pipeline after one of them (the
stage profile of ``benchmarks/frontend.py`` times these prefixes).
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.frontend import dense, features, hough, refine, verify

__all__ = ["STAGES", "TRACE_COUNT", "features_of", "candidates_of", "run"]

STAGES = (
    "lines",
    "corners",
    "votes",
    "peaks",
    "dense",
    "prescreen",
    "score",
    "refine",
    "rescore",
    "dedupe",
)
_FEATURE_STAGES = STAGES[:5]

# Incremented each time the pipeline is traced (tests assert one trace per shape bucket).
TRACE_COUNT = [0]


def _wall_pairs(lines, p, min_count: float = 30.0):
    """Whether two detected lines with >= ``min_count`` inliers each (on the Hough subsample)
    cross at >= ``corner_min_angle_deg``: the submap sees two non-parallel walls."""
    strong = lines["valid"] & (lines["count"] >= min_count)
    u = lines["u"]
    cr = jnp.abs(u[:, None, 0] * u[None, :, 1] - u[:, None, 1] * u[None, :, 0])
    wide = cr >= math.sin(math.radians(p.corner_min_angle_deg))
    return jnp.any(strong[:, None] & strong[None, :] & wide)


def features_of(points, origins, mask, feats, p, stop=None):
    """First half on one submap: ``points, origins (P, 2)``, ``mask (P,)``.

    Returns:
        dict with the compacted ``points``, ``origins``, ``mask``, ``n_valid``, the accumulator
        ``peaks (n_prescreen + dense_n, 3)`` and ``peak_ok``, and the debug counts ``n_lines``,
        ``n_corners``, ``walls``; or the output of stage ``stop`` when it is in this half.
    """
    TRACE_COUNT[0] += 1  # Python side effect: runs at trace time only
    # One compaction of the P points; every later subsample is a strided gather.
    points, origins, mask = features.compact(points, origins, mask)
    pts, org, ok, n_valid = features.subsample(
        points, origins, mask, p.hough_points, compacted=True
    )
    lines = features.detect_lines(pts, org, ok, p)
    if stop == "lines":
        return lines
    corners = features.detect_corners(lines, ok, p)
    if stop == "corners":
        return corners
    votes, w = hough.corner_votes(corners, feats.plan_corners, p)
    if stop == "votes":
        return votes, w
    peaks, _, peak_ok, _, _ = hough.vote(votes, w, p, p.n_prescreen)
    if stop == "peaks":
        return peaks, peak_ok
    if p.dense_n > 0:
        d_pose, d_ok = dense.peaks(pts, org, ok, lines, feats.dense, p)
        peaks = jnp.concatenate([peaks, d_pose])
        peak_ok = jnp.concatenate([peak_ok, d_ok])
    if stop == "dense":
        return peaks, peak_ok
    return dict(
        points=points,
        origins=origins,
        mask=mask,
        n_valid=n_valid,
        peaks=peaks,
        peak_ok=peak_ok,
        n_lines=jnp.sum(lines["valid"]),
        n_corners=jnp.sum(corners["valid"]),
        walls=_wall_pairs(lines, p),
    )


def candidates_of(f, feats, p, stop=None):
    """Second half on one submap, from its ``features_of`` dict ``f``.

    Returns:
        ``(pose (J, 3), score (J,), mask (J,), reason, debug)`` (see ``registration.register``
        and ``registration.register_debug``), or the output of stage ``stop``.
    """
    sub = partial(features.subsample, f["points"], f["origins"], f["mask"], compacted=True)
    n_valid, peaks, peak_ok = f["n_valid"], f["peaks"], f["peak_ok"]

    def scorer(n):
        vp, vo, vok, _ = sub(n)
        q, q_ok = verify.free_samples(vp, vo, vok, p.ray_samples, p.ray_stop)
        return partial(
            verify.scores, pts=vp, ok=vok, q=q, q_ok=q_ok, feats=feats, sigma=p.sigma_occ,
            lam=p.lambda_free,
        )  # fmt: skip

    has_walls = jnp.any(feats.rasters.wall)
    reason = jnp.where(
        n_valid == 0,
        1,
        jnp.where(
            n_valid < p.min_points, 2, jnp.where(~has_walls, 4, jnp.where(~jnp.any(peak_ok), 3, 0))
        ),
    ).astype(jnp.int32)
    peak_ok &= reason == 0

    def rank(poses, sc, ok, n):
        order = jnp.argsort(-jnp.where(ok, sc, -jnp.inf), stable=True)[:n]
        return poses[order], sc[order], ok[order]

    # Prescreen every peak, fully score the best n_hough, refine the best J.
    pose_h, _, ok_h = rank(peaks, scorer(p.prescreen_points)(peaks), peak_ok, p.n_hough)
    if stop == "prescreen":
        return pose_h, ok_h
    score = scorer(p.verify_points)
    pose0, sc0, ok0 = rank(pose_h, score(pose_h), ok_h, p.J)
    if stop == "score":
        return pose0, sc0, ok0
    rp, _, rok, _ = sub(p.refine_points)
    pose1 = refine.refine(pose0, rp, rok, feats, p)
    if stop == "refine":
        return pose1
    pose1 = jnp.where(jnp.all(jnp.isfinite(pose1), -1, keepdims=True), pose1, pose0)
    sc1 = score(pose1)
    if stop == "rescore":
        return pose1, sc1
    # Keep the refined pose only where the same score improved.
    better = sc1 > sc0
    pose1 = jnp.where(better[:, None], pose1, pose0)
    sc1 = jnp.where(better, sc1, sc0)
    refined = pose1  # same order as pose0 (debug: per-candidate refinement gain)
    pose1, sc1, ok1 = rank(pose1, sc1, ok0, p.J)
    # A candidate that converged onto a better-ranked one is a duplicate.
    dxy, dth = se2.distance_pair(pose1[:, None, :], pose1[None, :, :])
    close = (dxy <= p.dedupe_xy) & (dth <= math.radians(p.dedupe_deg))
    earlier = jnp.arange(p.J)[None, :] < jnp.arange(p.J)[:, None]
    keep = ok1 & ~jnp.any(close & earlier & ok1[None, :], axis=1)
    pose1, sc1, keep = rank(pose1, sc1, keep, p.J)
    debug = dict(
        pose0=pose0,
        refined=refined,
        ok0=ok0,
        n_lines=f["n_lines"],
        n_corners=f["n_corners"],
        walls=f["walls"],
    )
    return (
        jnp.where(keep[:, None], pose1, 0.0),
        jnp.where(keep, sc1, -jnp.inf),
        keep,
        reason,
        debug,
    )


def run(points, origins, mask, feats, p, stop=None):
    """The pipeline on a batch ``points, origins (N, P, 2)``, ``mask (N, P)``: ``features_of``
    submap after submap, ``candidates_of`` vmapped over the batch (module docstring).

    Returns:
        ``candidates_of``'s outputs with a leading ``N`` axis, or those of stage ``stop``.
    """
    one = lambda a: features_of(*a, feats=feats, p=p, stop=stop)  # noqa: E731
    f = jax.lax.map(one, (points, origins, mask))
    if stop in _FEATURE_STAGES:
        return f
    return jax.vmap(partial(candidates_of, feats=feats, p=p, stop=stop))(f)
