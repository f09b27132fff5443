"""Windows of many runs padded on the host into one batch (``WindowBatch``).

``pack`` lays the submaps of every window of every run into one ``SubmapBatch`` (points in a
power-of-two capacity bucket, their evidence samples alongside) and the runs' trajectories
and window ranges into one ``RunBatch``; ``concat`` joins packed batches without their points
(what the decision layer and the scorer need). Shapes are fixed on the host; the kernels mask.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from mfcl_jax.windows.arrays import (
    EVIDENCE_POINTS,
    Evidence,
    RunBatch,
    SubmapBatch,
    bucket,
    end_sample,
    evidence_sample,
)

__all__ = ["WindowBatch", "pack", "concat"]


@dataclass(frozen=True, eq=False)
class WindowBatch:
    """Windows of many runs, padded into one batch (host arrays).

    Attributes:
        submaps: ``SubmapBatch`` of every window of every run (``N`` rows).
        runs: ``RunBatch`` (``R`` runs, ``K`` windows, ``T`` keyframes max).
        building: ``(N,)`` int32 building index of each submap.
        run_building: ``(R,)`` int32 building index of each run.
        evidence: ``Evidence`` sample of every submap (kept by ``concat``).
        windows: the ``R`` ``Windows`` (for times, odometry and keyframes when scoring).
    """

    submaps: SubmapBatch
    runs: RunBatch
    building: np.ndarray
    run_building: np.ndarray
    evidence: Evidence
    windows: list = field(default_factory=list)


def _pad_rows(a: np.ndarray, n: int) -> np.ndarray:
    """Pads ``a`` to ``n`` rows by repeating its last row (keeps padded poses finite)."""
    a = np.asarray(a)
    if len(a) >= n:
        return a[:n]
    return np.concatenate([a, np.repeat(a[-1:], n - len(a), axis=0)])


def pack(items, capacity: int | None = None, min_capacity: int = 256) -> WindowBatch:
    """Pads the windows of many runs into one ``WindowBatch``.

    Args:
        items: ``(seq, windows, building)`` per run: the ``ScanSequence`` (not read: the
            ``Windows`` carry the run's odometry and segments), its ``Windows``, its building
            index.
        capacity: point capacity (default: the bucket of the fullest submap).
        min_capacity: the smallest bucket.
    """
    items = list(items)
    n = sum(len(w) for _, w, _ in items)
    most = max((len(p) for _, w, _ in items for p in w.points), default=0)
    cap = capacity or bucket(most, minimum=min_capacity)
    if most > cap:
        raise ValueError(f"pack: a submap holds {most} points, over capacity {cap}")
    points = np.zeros((n, cap, 2), np.float32)
    origins = np.zeros((n, cap, 2), np.float32)
    mask = np.zeros((n, cap), bool)
    ev_p = np.zeros((n, EVIDENCE_POINTS, 2), np.float32)
    ev_o = np.zeros((n, EVIDENCE_POINTS, 2), np.float32)
    ev_m = np.zeros((n, EVIDENCE_POINTS), bool)
    end_p = np.zeros((n, EVIDENCE_POINTS, 2), np.float32)
    end_m = np.zeros((n, EVIDENCE_POINTS), bool)
    X = np.zeros((n, 3), np.float32)
    run = np.zeros(n, np.int32)
    window = np.zeros(n, np.int32)
    t = np.zeros(n, np.float64)
    building = np.zeros(n, np.int32)
    R = len(items)
    T = max([len(w.keyframes) for _, w, _ in items] + [1])
    K = max([len(w) for _, w, _ in items] + [1])
    traj = np.zeros((R, T, 3), np.float32)
    traj_seg = np.full((R, T), -1, np.int32)
    traj_mask = np.zeros((R, T), bool)
    window_start = np.zeros((R, K), np.int32)
    window_end = np.zeros((R, K), np.int32)
    window_mask = np.zeros((R, K), bool)
    submap = np.full((R, K), -1, np.int32)
    i = 0
    for r, (_, w, b) in enumerate(items):
        m = len(w.keyframes)
        traj[r] = _pad_rows(w.odometry, T)
        traj_seg[r, :m] = w.segments
        traj_mask[r, :m] = True
        for k, (pts, org, last) in enumerate(zip(w.points, w.origins, w.last_points, strict=True)):
            points[i, : len(pts)], origins[i, : len(pts)], mask[i, : len(pts)] = pts, org, True
            ev_p[i], ev_o[i], ev_m[i] = evidence_sample(pts, org)
            end_p[i], end_m[i] = end_sample(last)
            X[i], run[i], window[i], t[i], building[i] = w.X[k], r, k, w.t[k], b
            submap[r, k] = i
            i += 1
        window_start[r, : len(w)] = w.bounds[:, 0]
        window_end[r, : len(w)] = w.bounds[:, 1]
        window_mask[r, : len(w)] = True
    subs = SubmapBatch(points, origins, mask, X, run, window, t, np.zeros(n, np.int32))
    runs = RunBatch(traj, traj_seg, traj_mask, window_start, window_end, window_mask, submap)
    rb = np.asarray([b for *_, b in items], np.int32)
    ev = Evidence(ev_p, ev_o, ev_m, end_p, end_m)
    return WindowBatch(subs, runs, building, rb, ev, [w for _, w, _ in items])


def concat(batches) -> WindowBatch:
    """Joins ``WindowBatch``es into one WITHOUT their points (what the decision layer and the
    scorer need: odometry, windows, building indices); runs and submaps are re-indexed in
    order. ``Windows`` lose their point lists too."""
    batches = list(batches)
    n = sum(b.submaps.n for b in batches)
    T = max(int(b.runs.traj.shape[1]) for b in batches)
    K = max(int(b.runs.window_mask.shape[1]) for b in batches)

    def pad(a, axis, size, value):
        a = np.asarray(a)
        width = [(0, 0)] * a.ndim
        width[axis] = (0, size - a.shape[axis])
        return np.pad(a, width, constant_values=value)

    subs, runs, off_r, off_n = [], [], 0, 0
    for b in batches:
        s, r = b.submaps, b.runs
        subs.append(
            (np.asarray(s.X), np.asarray(s.run) + off_r, np.asarray(s.window), np.asarray(s.t))
        )
        runs.append(
            (
                pad(r.traj, 1, T, 0.0),
                pad(r.traj_seg, 1, T, -1),
                pad(r.traj_mask, 1, T, False),
                pad(r.window_start, 1, K, 0),
                pad(r.window_end, 1, K, 0),
                pad(r.window_mask, 1, K, False),
                pad(
                    np.where(np.asarray(r.submap) >= 0, np.asarray(r.submap) + off_n, -1), 1, K, -1
                ),
            )
        )
        off_r += r.n_runs
        off_n += s.n
    X, run, window, t = (np.concatenate(c) for c in zip(*subs, strict=True))
    sub = SubmapBatch(
        np.zeros((n, 0, 2), np.float32),
        np.zeros((n, 0, 2), np.float32),
        np.zeros((n, 0), bool),
        X,
        run.astype(np.int32),
        window,
        t,
        np.zeros(n, np.int32),
    )
    rb = RunBatch(*(np.concatenate(c) for c in zip(*runs, strict=True)))
    light = [replace(w, points=[], origins=[]) for b in batches for w in b.windows]
    ev = Evidence(*(np.concatenate([getattr(b.evidence, f) for b in batches]) for f in
                    ("points", "origins", "mask", "end_points", "end_mask")))  # fmt: skip
    return WindowBatch(
        sub,
        rb,
        np.concatenate([b.building for b in batches]),
        np.concatenate([b.run_building for b in batches]),
        ev,
        light,
    )
