"""Front-end entry points: parameters, floor-plan features, the batched ``register`` kernel,
host-side input hygiene, and a CSV adapter for external front-ends.

Pipeline per submap (vmapped over the batch axis): subsample -> line Hough -> corners ->
corner-pair pose votes -> yaw slabs + xy accumulators -> top ``n_hough`` cells -> verify ->
adam refinement -> re-score -> sort + dedupe -> top ``J``.

All sizes and thresholds live in ``FrontendParams`` (frozen, hashable): they are static, so a
change recompiles. ``make_register(params)`` jits once per (params, shape bucket); call the
returned function for every batch of that bucket.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.batch import Candidates, SubmapBatch
from mfcl_jax.floorplan.raster import Rasters
from mfcl_jax.frontend import features, hough, refine, verify

__all__ = [
    "FrontendParams",
    "FloorplanFeatures",
    "build_features",
    "register",
    "register_debug",
    "make_register",
    "sanitize_submaps",
    "load_candidates_csv",
    "TRACE_COUNT",
]

# Incremented each time ``register`` is traced (tests assert one trace per shape bucket).
TRACE_COUNT = [0]


@dataclass(frozen=True)
class FrontendParams:
    """Front-end settings (all static). Distances in metres, angles in degrees."""

    J: int = 32  # candidates returned per submap (<= n_hough)
    min_points: int = 50  # fewer valid points -> reason 2
    # line Hough over a strided subsample
    hough_points: int = 768
    line_theta_bins: int = 90
    line_rho_res: float = 0.10
    rho_max: float = 20.0
    n_lines: int = 16
    line_nms_deg: float = 4.0
    line_nms_rho: float = 0.35
    inlier_band: float = 0.10
    min_line_pts: int = 12
    min_line_frac: float = 0.02
    # corners
    corner_min_angle_deg: float = 30.0
    arm_min: float = 0.10
    arm_max: float = 1.50
    min_arm_pts: int = 5
    n_corners: int = 32
    corner_angle_tol_deg: float = 6.0
    # pose accumulator (evaluated at the votes)
    cell: float = 0.15
    yaw_bin_deg: float = 1.0
    nms_xy: float = 0.45
    nms_deg: float = 3.0
    max_votes: int = 512
    n_hough: int = 64
    # verification (nearest-cell lookups of host-precomputed kernels)
    verify_points: int = 512
    ray_samples: int = 2
    ray_stop: float = 0.30
    sigma_occ: float = 0.10
    sigma_free: float = 0.05
    lambda_free: float = 1.0
    # refinement (bilinear, occupancy term) of the top J verified candidates
    refine_points: int = 128
    refine_steps: int = 20
    refine_lr: float = 0.03
    sigma_refine: float = 0.20
    yaw_lever: float = 5.0
    # final de-duplication of refined candidates
    dedupe_xy: float = 0.30
    dedupe_deg: float = 2.0

    def __post_init__(self):
        if not 1 <= self.J <= self.n_hough:
            raise ValueError(
                f"FrontendParams: need 1 <= J <= n_hough, got {self.J=}, {self.n_hough=}"
            )
        for name in ("hough_points", "n_lines", "n_corners", "max_votes", "verify_points",
                     "refine_points", "ray_samples"):
            if getattr(self, name) < 1:
                raise ValueError(f"FrontendParams: {name} must be >= 1, got {getattr(self, name)}")
        for name in ("cell", "line_rho_res", "rho_max", "inlier_band", "sigma_occ", "sigma_free"):
            if not getattr(self, name) > 0:
                raise ValueError(f"FrontendParams: {name} must be > 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class FloorplanFeatures:
    """Host-prepared plan features (a pytree of arrays).

    Attributes:
        rasters: ``Rasters`` (JAX arrays); grid geometry and the wall mask.
        reward, penalty: ``(H, W)`` verification terms (``verify.kernels``).
        reward_smooth: ``(H, W)`` occupancy kernel at ``sigma_refine`` for refinement.
        corner_pos: ``(C, 2)``; corner_a1, corner_a2: ``(C,)`` edge angles (rad);
        corner_kind: ``(C,)`` int32; corner_valid: ``(C,)`` bool.
    """

    rasters: Rasters
    reward: jax.Array
    penalty: jax.Array
    reward_smooth: jax.Array
    corner_pos: jax.Array
    corner_a1: jax.Array
    corner_a2: jax.Array
    corner_kind: jax.Array
    corner_valid: jax.Array


jax.tree_util.register_dataclass(
    FloorplanFeatures,
    data_fields=["rasters", "reward", "penalty", "reward_smooth", "corner_pos", "corner_a1",
                 "corner_a2", "corner_kind", "corner_valid"],
    meta_fields=[],
)


def build_features(fp, params: FrontendParams = FrontendParams(), res: float = 0.10,
                   rasters: Rasters | None = None, corners=None) -> FloorplanFeatures:
    """Builds ``FloorplanFeatures`` from a ``Floorplan`` (or from given rasters + corners).

    Args:
        fp: a ``Floorplan``, or None when ``rasters`` and ``corners`` are given.
        params: front-end parameters (kernel widths).
        res: raster resolution (m).
        rasters: optional precomputed (possibly padded, see ``raster.pad_to``) rasters.
        corners: optional ``(pos, a1, a2, kind, valid)`` as from ``features.floorplan_corners``.
    """
    if rasters is None:
        rasters = fp.rasterize(res=res)
    if corners is None:
        corners = features.floorplan_corners(fp)
    rasters = rasters.to_numpy()
    reward, penalty = verify.kernels(rasters.dist, rasters.inside, params.sigma_occ,
                                     params.sigma_free)
    smooth, _ = verify.kernels(rasters.dist, rasters.inside, params.sigma_refine, 1.0)
    pos, a1, a2, kind, valid = (np.asarray(c) for c in corners)
    return FloorplanFeatures(
        rasters=rasters.to_jax(),
        reward=jnp.asarray(reward),
        penalty=jnp.asarray(penalty),
        reward_smooth=jnp.asarray(smooth),
        corner_pos=jnp.asarray(pos, jnp.float32).reshape(-1, 2),
        corner_a1=jnp.asarray(a1, jnp.float32).reshape(-1),
        corner_a2=jnp.asarray(a2, jnp.float32).reshape(-1),
        corner_kind=jnp.asarray(kind, jnp.int32).reshape(-1),
        corner_valid=jnp.asarray(valid, bool).reshape(-1),
    )


def _register_one(points, origins, mask, feats: FloorplanFeatures, p: FrontendParams):
    TRACE_COUNT[0] += 1  # Python side effect: runs at trace time only
    pts, org, ok, n_valid = features.subsample(points, origins, mask, p.hough_points)
    lines = features.detect_lines(pts, org, ok, p)
    corners = features.detect_corners(lines, ok, p)
    plan = (feats.corner_pos, feats.corner_a1, feats.corner_a2, feats.corner_kind,
            feats.corner_valid)
    votes, w = hough.corner_votes(corners, plan, p)
    pose0, _, cand_ok, _, _ = hough.vote(votes, w, p)

    r = feats.rasters
    vp, vo, vok, _ = features.subsample(points, origins, mask, p.verify_points)
    q, q_ok = verify.free_samples(vp, vo, vok, p.ray_samples, p.ray_stop)

    def scores(poses):
        return jax.vmap(
            lambda y: verify.score(y, vp, vok, q, q_ok, r, feats.reward, feats.penalty,
                                   p.lambda_free)
        )(poses)

    has_walls = jnp.any(r.wall)
    reason = jnp.where(
        n_valid == 0, 1,
        jnp.where(n_valid < p.min_points, 2,
                  jnp.where(~has_walls, 4, jnp.where(~jnp.any(cand_ok), 3, 0))),
    ).astype(jnp.int32)
    cand_ok &= reason == 0

    def rank(poses, sc, ok, n):
        order = jnp.argsort(-jnp.where(ok, sc, -jnp.inf), stable=True)[:n]
        return poses[order], sc[order], ok[order]

    # Verify all voted poses, refine the best J, re-score, re-sort.
    pose0, sc0, ok0 = rank(pose0, scores(pose0), cand_ok, p.J)
    rp, _, rok, _ = features.subsample(points, origins, mask, p.refine_points)
    pose1 = refine.refine(pose0, rp, rok, r, feats.reward_smooth, p)
    pose1 = jnp.where(jnp.all(jnp.isfinite(pose1), -1, keepdims=True), pose1, pose0)
    sc1 = scores(pose1)
    # Keep the refined pose only where it scores at least as well as the voted one.
    better = sc1 >= sc0
    pose1 = jnp.where(better[:, None], pose1, pose0)
    sc1 = jnp.where(better, sc1, sc0)
    pose1, sc1, ok1 = rank(pose1, sc1, ok0, p.J)
    # A candidate that converged onto a better-ranked one is a duplicate.
    dxy, dth = se2.distance_pair(pose1[:, None, :], pose1[None, :, :])
    close = (dxy <= p.dedupe_xy) & (dth <= math.radians(p.dedupe_deg))
    earlier = jnp.arange(p.J)[None, :] < jnp.arange(p.J)[:, None]
    keep = ok1 & ~jnp.any(close & earlier & ok1[None, :], axis=1)
    pose1, sc1, keep = rank(pose1, sc1, keep, p.J)
    return (jnp.where(keep[:, None], pose1, 0.0), jnp.where(keep, sc1, -jnp.inf), keep, reason,
            pose0)


def register(submaps: SubmapBatch, feats: FloorplanFeatures, params: FrontendParams) -> Candidates:
    """Registers every submap of the batch against one floor plan.

    Pure (no jit inside); use ``make_register`` to get the jitted version.

    Args:
        submaps: ``SubmapBatch`` with ``points``/``origins`` ``(N, P, 2)`` and ``mask (N, P)``.
        feats: ``FloorplanFeatures`` of the building.
        params: ``FrontendParams`` (static).

    Returns:
        ``Candidates`` with ``pose (N, J, 3)``, ``score (N, J)`` (-inf where masked),
        ``mask (N, J)``, ``reason (N,)``.
    """
    fn = jax.vmap(partial(_register_one, feats=feats, p=params))
    pose, score, mask, reason, _ = fn(submaps.points, submaps.origins, submaps.mask)
    return Candidates(pose=pose, score=score, mask=mask, reason=reason)


def register_debug(submaps: SubmapBatch, feats: FloorplanFeatures, params: FrontendParams):
    """Like ``register`` but also returns the top-J voted poses before refinement ``(N, J, 3)``
    (benchmarks compare pose errors before and after refinement)."""
    fn = jax.vmap(partial(_register_one, feats=feats, p=params))
    pose, score, mask, reason, pose0 = fn(submaps.points, submaps.origins, submaps.mask)
    return Candidates(pose=pose, score=score, mask=mask, reason=reason), pose0


def make_register(params: FrontendParams = FrontendParams()):
    """Returns ``f(submaps, feats) -> Candidates``, jitted once; reuse it for every batch."""
    return jax.jit(partial(register, params=params))


def sanitize_submaps(batch: SubmapBatch) -> SubmapBatch:
    """Host side: masks out non-finite points/origins and counts them in ``n_dropped``."""
    pts, org, mask = (np.asarray(a) for a in (batch.points, batch.origins, batch.mask))
    finite = np.all(np.isfinite(pts), -1) & np.all(np.isfinite(org), -1)
    bad = mask & ~finite
    return SubmapBatch(
        points=np.where(finite[..., None], pts, 0.0).astype(np.float32),
        origins=np.where(finite[..., None], org, 0.0).astype(np.float32),
        mask=mask & finite,
        X=batch.X,
        run=batch.run,
        window=batch.window,
        t=batch.t,
        n_dropped=(np.asarray(batch.n_dropped) + bad.sum(-1)).astype(np.int32),
    )


_CSV_FIELDS = ("submap", "x", "y", "yaw_deg", "score")


def load_candidates_csv(path, n_submaps: int, J: int) -> Candidates:
    """Reads candidates from an external front-end.

    The CSV has a header with at least ``submap, x, y, yaw_deg, score``; one row per candidate
    (``submap`` is the 0-based row of the ``SubmapBatch``). Each submap keeps its ``J``
    highest-scoring rows; submaps without rows get reason 3 ("no features").

    Raises:
        ValueError: naming the file, line and field of the first bad value.
    """
    path = Path(path)
    per: list[list[tuple[float, float, float, float]]] = [[] for _ in range(n_submaps)]
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [f for f in _CSV_FIELDS if f not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(
                f"{path}: line 1: missing column(s) {missing}; need {list(_CSV_FIELDS)}"
            )
        for row in reader:
            line = reader.line_num
            vals = {}
            for f in _CSV_FIELDS:
                raw = row.get(f)
                try:
                    v = int(raw) if f == "submap" else float(raw)
                except (TypeError, ValueError):
                    msg = f"{path}: line {line}: field {f!r}: bad value {raw!r}"
                    raise ValueError(msg) from None
                if f != "submap" and not math.isfinite(v):
                    raise ValueError(f"{path}: line {line}: field {f!r}: non-finite value {raw!r}")
                vals[f] = v
            if not 0 <= vals["submap"] < n_submaps:
                raise ValueError(
                    f"{path}: line {line}: field 'submap': {vals['submap']} not in [0, {n_submaps})"
                )
            per[vals["submap"]].append(
                (vals["score"], vals["x"], vals["y"], math.radians(vals["yaw_deg"]))
            )
    pose = np.zeros((n_submaps, J, 3), np.float32)
    score = np.full((n_submaps, J), -np.inf, np.float32)
    mask = np.zeros((n_submaps, J), bool)
    for i, rows in enumerate(per):
        rows.sort(key=lambda r: -r[0])
        for j, (s, x, y, th) in enumerate(rows[:J]):
            pose[i, j] = (x, y, float(se2.wrap(th)))
            score[i, j] = s
            mask[i, j] = True
    reason = np.where(mask.any(1), 0, 3).astype(np.int32)
    return Candidates(pose=pose, score=score, mask=mask, reason=reason)
