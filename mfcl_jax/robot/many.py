"""Many recordings localized in one batch (``mfcl localize A B C``).

The batch path of the study, in chunks of ``chunk`` recordings so that memory stays bounded
whatever their number: the windows of a chunk are cut together (``windows.cut_many``: one
batched LiDAR odometry), registered by one ``FrontEnd`` and decided by the one decision layer
(``decision.runs``: ``vmap`` over runs of ``lax.scan(layer.update)``, the ``update`` a robot
calls). Every chunk shares one compilation: the capacities are sized once, from every
recording's input odometry, before any work.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import jax
import numpy as np

from mfcl_jax import windows as W
from mfcl_jax.robot.localizer import LocalizeParams, record_of
from mfcl_jax.robot.progress import COMPILING, Progress

__all__ = ["BatchResult", "localize_batch", "CHUNK"]

CHUNK = 8  # recordings per chunk


@dataclass(frozen=True)
class BatchResult:
    """The windows of one recording.

    Attributes:
        records: one decisions-file record per window (``localizer.record_of``).
        details: per window, the status line's detail (points, candidates).
    """

    records: list
    details: list


def _floors(seqs, p: W.WindowParams) -> dict:
    """Capacities that hold every recording (from the input odometry, before scan matching,
    whose jump test can only split segments)."""
    n_win, n_kf, step, head = 1, 1, 16, 0
    for seq in seqs:
        kf = W.keyframes(seq.odometry, p.keyframe_spacing, p.keyframe_turn_deg)
        raw = np.asarray(seq.odometry, np.float64)[kf]
        seg = W.odometry_segments(raw, np.asarray(seq.times)[kf])
        b = W.segment_bounds(raw, seg, p.d_s, p.step)
        n_kf = max(n_kf, len(kf))
        if len(b):
            n_win = max(n_win, len(b))
            step = max(step, int(np.max(np.diff(b[:, 1]), initial=0)))
            head = max(head, int(np.max(b[:, 1] - b[:, 0] + 1)))
    step = -(-step // 16) * 16
    return dict(min_windows=n_win, min_traj=n_kf, min_step=step,
                min_head=-(-max(head - step, 0) // 16) * 16)  # fmt: skip


def localize_batch(floorplans, seqs, params: LocalizeParams | None = None, progress=None,
                   chunk: int | None = None) -> Iterator[tuple[int, BatchResult]]:  # fmt: skip
    """Decisions at every window of every sequence, chunk by chunk.

    Args:
        floorplans: the ``Floorplan`` of each sequence.
        seqs: ``ScanSequence``s.
        params: ``LocalizeParams`` (shared).
        progress: ``Progress`` for stages (default: silent).
        chunk: the most recordings decided together (default ``CHUNK``).

    Yields:
        ``(index, BatchResult)`` per sequence, in order, as each chunk completes.
    """
    from mfcl_jax.decision.inputs import run_inputs
    from mfcl_jax.decision.lanes import make_lanes
    from mfcl_jax.decision.runs import decide_runs, stack_buildings
    from mfcl_jax.frontend.driver import FrontEnd

    params = params or LocalizeParams()
    progress = progress or Progress(False)
    chunk = chunk or CHUNK
    floors = _floors(seqs, params.window)
    steps = {k: floors.pop(k) for k in ("min_step", "min_head")}
    plans = list(dict.fromkeys(id(fp) for fp in floorplans))
    by_id = {id(fp): fp for fp in floorplans}
    unique = [by_id[i] for i in plans]
    fe = FrontEnd(unique, params.frontend, chunk=16)
    p, lanes, spec = make_lanes(params.decision, (params.policy,), baselines=False,
                                primary=params.policy)  # fmt: skip
    buildings = stack_buildings(unique, spec)
    cap = W.bucket(params.window.capacity, 256)
    # chunks of equal size (20 recordings: 7, 7, 6), the last padded to it, so that every
    # chunk shares one compilation and few idle rows are computed
    n_chunks = max(1, math.ceil(len(seqs) / chunk))
    size = max(1, math.ceil(len(seqs) / n_chunks))
    for c0 in range(0, len(seqs), size):
        idx = list(range(c0, min(c0 + size, len(seqs))))
        with progress.stage(f"recordings {idx[0] + 1}-{idx[-1] + 1} of {len(seqs)}: cutting "
                            "windows (LiDAR odometry)"):  # fmt: skip
            wins = W.cut_many(((seqs[i], params.window) for i in idx), rows=size)
        items = [(seqs[i], w, plans.index(id(floorplans[i])))
                 for i, w in zip(idx, wins, strict=True) if len(w)]  # fmt: skip
        done = {i: BatchResult([], []) for i in idx}
        if items:
            batch = W.pack(items, capacity=cap)
            n = batch.submaps.n
            first = COMPILING if c0 == 0 else "registering"
            with progress.stage(f"registering {n} windows ({first})"):
                cands = fe.register(batch.submaps, batch.building, keep=True)
            with progress.stage(f"deciding {n} windows ({first})"):
                dec, _ = decide_runs(run_inputs(batch, cands, **steps), batch.run_building,
                                     unique, p, lanes, spec, min_runs=size,
                                     buildings=buildings, **floors)  # fmt: skip
            valid = np.asarray(cands.mask).sum(1)
            r = 0
            for i, w in zip(idx, wins, strict=True):
                if not len(w):
                    continue
                res = done[i]
                offset = floorplans[i].offset
                for k in range(len(w)):
                    d = jax.tree.map(lambda a, r=r, k=k: a[r, k, 0], dec)
                    seg = int(w.segments[w.bounds[k, 0]])  # k + 1: over the whole recording
                    res.records.append(record_of(d, k + 1, float(w.t[k]), w.X[k], w.X_input[k],
                                                 offset, seg, params.unique_llr))  # fmt: skip
                    sub = int(batch.runs.submap[r, k])
                    thin = f" rethinned voxel={w.voxel[k]:.2f}" if W.rethinned(w)[k] else ""
                    res.details.append(f"pts={len(w.points[k])}{thin} cands={int(valid[sub])}")
                r += 1
        yield from ((i, done[i]) for i in idx)
