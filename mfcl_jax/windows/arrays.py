"""The padded arrays of windows: submaps, runs and evidence samples.

Data flows one way: ``windows.pack`` -> ``SubmapBatch`` + ``RunBatch`` -> front-end
(``frontend.candidates.Candidates``) -> decision layer. Ground truth is not here: it stays in
the recordings and only the scorer reads it. All are JAX pytrees of arrays padded on the
host; every ragged axis has a boolean mask.

Shapes: ``N`` submaps (all runs stacked), ``P`` points per submap (capacity bucket), ``R`` runs,
``K`` windows per run (max), ``T`` trajectory samples per run (max).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import jax
import numpy as np

__all__ = [
    "SubmapBatch",
    "RunBatch",
    "Evidence",
    "EVIDENCE_POINTS",
    "evidence_sample",
    "end_sample",
    "bucket",
    "pad_submaps",
]


def _register(cls, meta=()):
    data = [f.name for f in fields(cls) if f.name not in meta]
    jax.tree_util.register_dataclass(cls, data_fields=data, meta_fields=list(meta))
    return cls


def bucket(n: int, minimum: int = 256) -> int:
    """Capacity bucket: the next power of two >= ``n`` (at least ``minimum``)."""
    cap = minimum
    while cap < n:
        cap *= 2
    return cap


@dataclass(frozen=True)
class SubmapBatch:
    """Submaps of every run stacked on one axis.

    Attributes:
        points: ``(N, P, 2)`` float32 points in the submap frame ``S_i``.
        origins: ``(N, P, 2)`` float32 sensor position (in ``S_i``) when each point was measured,
            so the ray origin -> point is known free space.
        mask: ``(N, P)`` bool, valid points.
        X: ``(N, 3)`` float32 ``^L T_{S_i}`` from odometry.
        run: ``(N,)`` int32 run index.
        window: ``(N,)`` int32 window index ``k - 1`` within the run (0-based).
        t: ``(N,)`` float64 time stamp of the window's last scan (s).
        n_dropped: ``(N,)`` int32 points dropped on the host (NaN/inf or over capacity).
    """

    points: jax.Array
    origins: jax.Array
    mask: jax.Array
    X: jax.Array
    run: jax.Array
    window: jax.Array
    t: jax.Array
    n_dropped: jax.Array

    @property
    def n(self) -> int:
        return int(self.points.shape[0])


@dataclass(frozen=True)
class RunBatch:
    """Per-run trajectories and windows, for the gate and the prefix masks.

    Attributes:
        traj: ``(R, T, 3)`` odometry poses ``^L T_t`` of the scans (sensor poses in L).
        traj_seg: ``(R, T)`` int32 odometry segment of each pose (``Windows.segments``): 0,
            plus one after every odometry jump; -1 where padded.
        traj_mask: ``(R, T)`` bool.
        window_start: ``(R, K)`` int32 index into ``traj`` of window k's first scan.
        window_end: ``(R, K)`` int32 index into ``traj`` of window k's last scan.
        window_mask: ``(R, K)`` bool, valid windows.
        submap: ``(R, K)`` int32 row of ``SubmapBatch`` holding window k (-1 where padded).
    """

    traj: jax.Array
    traj_seg: jax.Array
    traj_mask: jax.Array
    window_start: jax.Array
    window_end: jax.Array
    window_mask: jax.Array
    submap: jax.Array

    @property
    def n_runs(self) -> int:
        return int(self.traj.shape[0])

    @property
    def n_windows(self) -> int:
        return int(self.window_mask.shape[1])


@dataclass(frozen=True)
class Evidence:
    """A small, fixed-size sample of every submap, which the decision layer re-scores under
    competing anchors (``decision.certify``).

    Attributes:
        points: ``(N, P, 2)`` float32 points in the submap frame, evenly spread over the
            submap's points (deterministic).
        origins: ``(N, P, 2)`` their ray origins.
        mask: ``(N, P)`` bool.
        end_points: ``(N, P, 2)`` the points of the window's last scan (``end_sample``),
            which the layer fits to the plan where it reports a commit (``decision.drift``);
            ``None`` where a caller has none (the check is then off).
        end_mask: ``(N, P)`` bool.
    """

    points: jax.Array
    origins: jax.Array
    mask: jax.Array
    end_points: jax.Array | None = None
    end_mask: jax.Array | None = None


EVIDENCE_POINTS = 128


def evidence_sample(points, origins, n: int = EVIDENCE_POINTS):
    """``(pts (n, 2), org (n, 2), mask (n,))`` evenly spread over ``points (m, 2)``."""
    m = len(points)
    out_p = np.zeros((n, 2), np.float32)
    out_o = np.zeros((n, 2), np.float32)
    mask = np.zeros(n, bool)
    if m:
        idx = np.unique(np.linspace(0, m - 1, min(n, m)).round().astype(int))
        out_p[: len(idx)], out_o[: len(idx)], mask[: len(idx)] = points[idx], origins[idx], True
    return out_p, out_o, mask


def end_sample(last_scan, n: int = EVIDENCE_POINTS):
    """``(pts (n, 2), mask (n,))`` evenly spread over ``last_scan (m, 2)``, the window's last
    scan in its own frame (``Windows.last_points``): what ``decision.drift`` fits to the plan
    at a commit's reported pose."""
    pts = np.asarray(last_scan, np.float32).reshape(-1, 2)
    p, _, mask = evidence_sample(pts, np.zeros_like(pts), n)
    return p, mask


for _cls in (SubmapBatch, RunBatch, Evidence):
    _register(_cls)


def _pad_axis(a: np.ndarray, axis: int, size: int, value) -> np.ndarray:
    a = np.asarray(a)
    if a.shape[axis] == size:
        return a
    width = [(0, 0)] * a.ndim
    width[axis] = (0, size - a.shape[axis])
    return np.pad(a, width, constant_values=value)


def pad_submaps(sub: SubmapBatch, n: int | None = None, p: int | None = None) -> SubmapBatch:
    """Pads a ``SubmapBatch`` (host) to ``n`` submaps and ``p`` points; padding is masked out."""
    n = sub.n if n is None else n
    p = int(sub.points.shape[1]) if p is None else p
    if n < sub.n or p < int(sub.points.shape[1]):
        raise ValueError(f"pad_submaps: target ({n}, {p}) smaller than {sub.points.shape[:2]}")

    def both(a, value):
        return _pad_axis(_pad_axis(a, 0, n, value), 1, p, value)

    return SubmapBatch(
        points=both(sub.points, 0.0),
        origins=both(sub.origins, 0.0),
        mask=both(sub.mask, False),
        X=_pad_axis(sub.X, 0, n, 0.0),
        run=_pad_axis(sub.run, 0, n, -1),
        window=_pad_axis(sub.window, 0, n, -1),
        t=_pad_axis(sub.t, 0, n, np.nan),
        n_dropped=_pad_axis(sub.n_dropped, 0, n, 0),
    )
