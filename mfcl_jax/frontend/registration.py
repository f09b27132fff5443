"""Registration: submaps in, scored candidate poses out (the front-end's one kernel).

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

``register`` is pure; ``make_register(params)`` jits it once (with ``COMPILER_OPTIONS``) for
every batch of a shape bucket; ``frontend.driver.FrontEnd`` does that for every consumer.
"""

from __future__ import annotations

from functools import partial

import jax
import numpy as np

from mfcl_jax.frontend import pipeline
from mfcl_jax.frontend.candidates import Candidates
from mfcl_jax.frontend.params import COMPILER_OPTIONS, FrontendParams
from mfcl_jax.frontend.pipeline import STAGES, TRACE_COUNT
from mfcl_jax.frontend.plan import FloorplanFeatures
from mfcl_jax.windows.arrays import SubmapBatch

__all__ = [
    "register",
    "register_debug",
    "register_stages",
    "make_register",
    "sanitize_submaps",
    "STAGES",
    "TRACE_COUNT",
]


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
