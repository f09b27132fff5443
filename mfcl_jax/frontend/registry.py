"""Front-end entry points: parameters, floor-plan features, the batched ``register`` kernel,
host-side input hygiene, and a CSV adapter for external front-ends.

Pipeline per submap (``pipeline.py``): subsample -> line Hough -> corners -> corner-pair pose
votes -> top ``n_prescreen`` accumulator peaks, plus ``dense_n`` dense correlative peaks
(``dense.py``: wall directions fix the heading, an FFT correlation the translation; they need
no corners) -> cheap score on ``prescreen_points`` points ->
best ``n_hough`` -> full score -> best ``J`` -> Gauss-Newton refinement -> re-score -> keep the
refined pose where the score improved -> sort + dedupe. Every score is the same continuous
``verify.score`` at width ``sigma_occ``.

Why a prescreen: a corner-pair vote carries one unit, so the peaks of a submap whose corners are
mostly spurious (door jambs, clutter, walls cut by the 10 m crop) tie at one or two votes, and
ranking them by count drops the true pose at random. Scoring every peak on a small subsample is
cheap and ranks by what the scan actually shows.

All sizes and thresholds live in ``FrontendParams`` (frozen, hashable): they are static, so a
change recompiles. ``make_register(params)`` jits once per (params, shape bucket); call the
returned function for every batch of that bucket. ``common_features`` puts several buildings in
one bucket.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.windows.arrays import SubmapBatch
from mfcl_jax.frontend.candidates import Candidates
from mfcl_jax.floorplan.raster import Rasters, pad_to
from mfcl_jax.frontend import features, pipeline, verify
from mfcl_jax.frontend.dense import DenseFields, dense_fields
from mfcl_jax.frontend.pipeline import STAGES, TRACE_COUNT

__all__ = [
    "FrontendParams",
    "FloorplanFeatures",
    "build_features",
    "common_features",
    "common_shape",
    "register",
    "register_debug",
    "register_stages",
    "STAGES",
    "make_register",
    "sanitize_submaps",
    "TRACE_COUNT",
    "COMPILER_OPTIONS",
]


# XLA:CPU options for every compiled front-end call: fast math with NaN, Inf, division and
# library-function semantics kept, which leaves reassociation (and FMA contraction). Strict
# IEEE order keeps a loop that accumulates sums scalar; reassociated, XLA vectorises it:
# the refinement's nine running sums per point get 3.5x faster. Results move by rounding.
COMPILER_OPTIONS = {
    "xla_cpu_enable_fast_math": True,
    "xla_cpu_fast_math_honor_infs": True,
    "xla_cpu_fast_math_honor_nans": True,
    "xla_cpu_fast_math_honor_division": True,
    "xla_cpu_fast_math_honor_functions": True,
}


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
    max_votes: int = 2048
    n_hough: int = 64  # peaks that get the full score
    # prescreen: every accumulator peak (up to n_prescreen) scored on a small subsample
    n_prescreen: int = 256
    prescreen_points: int = 96
    # verification: continuous score (bilinear signed distance), see verify.py
    verify_points: int = 512
    ray_samples: int = 2
    ray_stop: float = 0.30
    sigma_occ: float = 0.07
    sigma_free: float = 0.05
    lambda_free: float = 1.0
    # refinement of the top J: optax, Gauss-Newton-preconditioned steps (refine.py),
    # sigma_refine -> sigma_occ; the heading is optimised in metres of arc at yaw_lever
    refine_points: int = 512
    refine_steps: int = 10
    sigma_refine: float = 0.30
    refine_max_step: float = 0.2  # per step, metres (of arc at yaw_lever for the heading)
    yaw_lever: float = 5.0
    # first-round adam learning rate: name kept so old configs still parse; setting it is an error
    refine_lr: float | None = None
    # final de-duplication of refined candidates
    dedupe_xy: float = 0.30
    dedupe_deg: float = 2.0
    # dense correlative hypotheses (dense.py), added to the accumulator peaks; 0 turns them off
    dense_n: int = 24  # polished dense peaks per submap
    dense_img: int = 96  # submap image side (coarse cells) of the correlation
    dense_res: float = 0.4  # coarse cell (m), rounded to a multiple of the raster cell
    dense_sub_dirs: int = 2  # submap wall directions
    dense_plan_dirs: int = 3  # plan wall directions
    dense_peaks_per_yaw: int = 3
    dense_lam: float = 1.0  # weight of the obstacle penalty (as the rival search)
    dense_polish_points: int = 128

    def __post_init__(self):
        if self.refine_lr is not None:
            raise ValueError(
                f"FrontendParams: refine_lr={self.refine_lr!r} is no longer used "
                "(refinement steps are Gauss-Newton-preconditioned, no learning "
                "rate); use refine_steps, sigma_refine, refine_max_step, yaw_lever"
            )
        if self.dense_n < 0 or self.dense_lam < 0:
            raise ValueError(
                f"FrontendParams: need dense_n >= 0 and dense_lam >= 0, got {self.dense_n=}, "
                f"{self.dense_lam=}"
            )
        if not 1 <= self.J <= self.n_hough <= self.n_prescreen <= self.max_votes:
            raise ValueError(
                "FrontendParams: need 1 <= J <= n_hough <= n_prescreen <= max_votes, got "
                f"{self.J=}, {self.n_hough=}, {self.n_prescreen=}, {self.max_votes=}"
            )
        for name in (
            "hough_points",
            "n_lines",
            "n_corners",
            "max_votes",
            "verify_points",
            "refine_points",
            "ray_samples",
            "prescreen_points",
            "refine_steps",
            "dense_img",
            "dense_sub_dirs",
            "dense_plan_dirs",
            "dense_peaks_per_yaw",
            "dense_polish_points",
        ):
            if getattr(self, name) < 1:
                raise ValueError(f"FrontendParams: {name} must be >= 1, got {getattr(self, name)}")
        for name in (
            "cell",
            "line_rho_res",
            "rho_max",
            "inlier_band",
            "sigma_occ",
            "sigma_free",
            "sigma_refine",
            "refine_max_step",
            "yaw_lever",
            "dense_res",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"FrontendParams: {name} must be > 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class FloorplanFeatures:
    """Host-prepared plan features (a pytree of arrays).

    Attributes:
        rasters: ``Rasters`` (JAX arrays); grid geometry and the wall mask.
        sdf4: ``(H + 1, W + 1, 4)`` signed wall-surface distance, ``verify.stack4`` layout.
        pen4: ``(H + 1, W + 1, 4)`` free-space penalty field, same layout.
        corner_pos: ``(C, 2)``; corner_a1, corner_a2: ``(C,)`` edge angles (rad);
        corner_kind: ``(C,)`` int32; corner_valid: ``(C,)`` bool.
        dense: ``dense.DenseFields`` (the dense hypotheses' plan fields and wall directions).
    """

    rasters: Rasters
    sdf4: jax.Array
    pen4: jax.Array
    corner_pos: jax.Array
    corner_a1: jax.Array
    corner_a2: jax.Array
    corner_kind: jax.Array
    corner_valid: jax.Array
    dense: DenseFields

    @property
    def plan_corners(self) -> tuple:
        """``(pos, a1, a2, kind, valid)``, the plan side of the corner correspondences."""
        return (
            self.corner_pos,
            self.corner_a1,
            self.corner_a2,
            self.corner_kind,
            self.corner_valid,
        )


jax.tree_util.register_dataclass(
    FloorplanFeatures,
    data_fields=[
        "rasters",
        "sdf4",
        "pen4",
        "corner_pos",
        "corner_a1",
        "corner_a2",
        "corner_kind",
        "corner_valid",
        "dense",
    ],
    meta_fields=[],
)


def _pad_corners(corners, capacity: int):
    pos, a1, a2, kind, valid = (np.asarray(c) for c in corners)
    n = int(np.sum(valid)) if valid.size else 0
    if np.any(valid[n:]):
        raise ValueError("build_features: corners must be packed (valid ones first)")
    if n > capacity:
        raise ValueError(f"build_features: {n} corners exceed corner_capacity={capacity}")

    def fit(v, fill):
        out = np.full((capacity, *v.shape[1:]), fill, v.dtype)
        k = min(len(v), capacity)
        out[:k] = v[:k]
        return out

    return (
        fit(pos.reshape(-1, 2), 0),
        fit(a1.reshape(-1), 0),
        fit(a2.reshape(-1), 0),
        fit(kind.reshape(-1), 0),
        fit(valid.reshape(-1), False),
    )


def build_features(
    fp,
    params: FrontendParams = FrontendParams(),
    res: float = 0.10,
    rasters: Rasters | None = None,
    corners=None,
    shape=None,
    n_rooms: int | None = None,
    corner_capacity: int | None = None,
) -> FloorplanFeatures:
    """Builds ``FloorplanFeatures`` from a ``Floorplan`` (or from given rasters + corners).

    Args:
        fp: a ``Floorplan``, or None when ``rasters`` and ``corners`` are given (the signed
            distance is then raster-based, accurate to half a cell).
        params: front-end parameters (kernel widths).
        res: raster resolution (m).
        rasters: optional precomputed (possibly padded, see ``raster.pad_to``) rasters.
        corners: optional ``(pos, a1, a2, kind, valid)`` as from ``features.floorplan_corners``.
        shape: optional ``(H, W)`` raster bucket to pad to (``raster.pad_to``), with
            ``n_rooms`` rooms; buildings with equal buckets share one compilation.
        corner_capacity: optional padded corner count (same purpose).
    """
    if rasters is None:
        if fp is None:
            raise ValueError("build_features: need a Floorplan or rasters + corners")
        rasters = fp.rasterize(res=res)
    if corners is None:
        if fp is None:
            raise ValueError("build_features: need a Floorplan or rasters + corners")
        corners = features.floorplan_corners(fp, capacity=corner_capacity)
    rasters = rasters.to_numpy()
    if shape is not None or n_rooms is not None:
        rasters = pad_to(rasters, tuple(shape or rasters.shape), n_rooms)
    if corner_capacity is not None:
        corners = _pad_corners(corners, corner_capacity)
    sdf, pen = verify.plan_fields(fp, rasters, params.sigma_free)
    pos, a1, a2, kind, valid = (np.asarray(c) for c in corners)
    return FloorplanFeatures(
        rasters=rasters.to_jax(),
        sdf4=jnp.asarray(verify.stack4(sdf, verify.FAR)),
        pen4=jnp.asarray(verify.stack4(pen, 1.0)),
        corner_pos=jnp.asarray(pos, jnp.float32).reshape(-1, 2),
        corner_a1=jnp.asarray(a1, jnp.float32).reshape(-1),
        corner_a2=jnp.asarray(a2, jnp.float32).reshape(-1),
        corner_kind=jnp.asarray(kind, jnp.int32).reshape(-1),
        corner_valid=jnp.asarray(valid, bool).reshape(-1),
        dense=dense_fields(rasters, a1, a2, valid, params),
    )


def common_shape(floorplans, res: float = 0.10, multiple: int = 64, margin: float = 1.0) -> dict:
    """The one shape bucket that fits every floor plan's features.

    Raster sides and the corner capacity are rounded up to a multiple of ``multiple``; the
    raster sides follow ``Floorplan.rasterize`` (``margin`` m around the bounds).

    Returns:
        ``build_features`` keyword arguments ``res, shape, n_rooms, corner_capacity``.
    """
    fps = list(floorplans)
    if not fps:
        raise ValueError("common_shape: no floor plans given")
    up = lambda n: max(multiple, -(-n // multiple) * multiple)  # noqa: E731

    def side(lo, hi):
        return int(math.ceil((hi + margin - (lo - margin)) / res))

    h = max(side(fp.bounds[1], fp.bounds[3]) for fp in fps)
    w = max(side(fp.bounds[0], fp.bounds[2]) for fp in fps)
    return dict(
        res=res,
        shape=(up(h), up(w)),
        n_rooms=max(len(fp.rooms) for fp in fps),
        corner_capacity=up(max(len(fp.corners[0]) for fp in fps)),
    )


def common_features(
    floorplans, params: FrontendParams = FrontendParams(), res: float = 0.10, multiple: int = 64
) -> list[FloorplanFeatures]:
    """Features of several buildings padded to one shape bucket (one compilation for all)."""
    fps = list(floorplans)
    kw = common_shape(fps, res, multiple)
    return [build_features(fp, params, **kw) for fp in fps]


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
    out = pipeline.run(submaps.points, submaps.origins, submaps.mask, feats, params)
    pose, score, mask, reason, _ = out
    return Candidates(pose=pose, score=score, mask=mask, reason=reason)


def register_debug(submaps: SubmapBatch, feats: FloorplanFeatures, params: FrontendParams):
    """Like ``register`` but also returns a dict of per-submap internals: ``pose0 (N, J, 3)``
    the verified poses before refinement, ``refined (N, J, 3)`` the same candidates after
    refinement (same order; equal where refinement was rejected), ``ok0 (N, J)``,
    ``n_lines``, ``n_corners`` and ``walls`` (two non-parallel walls seen) ``(N,)``."""
    out = pipeline.run(submaps.points, submaps.origins, submaps.mask, feats, params)
    pose, score, mask, reason, debug = out
    return Candidates(pose=pose, score=score, mask=mask, reason=reason), debug


def register_stages(
    submaps: SubmapBatch, feats: FloorplanFeatures, params: FrontendParams, stop: str
):
    """The pipeline of ``register`` cut after stage ``stop`` (one of ``STAGES``, in order),
    returning that stage's per-submap output: the stage profile of ``benchmarks/frontend.py``
    times these prefixes. ``stop="dedupe"`` is the whole of ``register_debug``."""
    if stop not in STAGES:
        raise ValueError(f"register_stages: stop={stop!r} is not one of {STAGES}")
    return pipeline.run(submaps.points, submaps.origins, submaps.mask, feats, params, stop)


def make_register(params: FrontendParams = FrontendParams()):
    """Returns ``f(submaps, feats) -> Candidates``, jitted once (with ``COMPILER_OPTIONS``);
    reuse it for every batch."""
    return jax.jit(partial(register, params=params), compiler_options=COMPILER_OPTIONS)


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
