"""Runs' windows laid out as the decision layer reads them (host arrays, ``(R, K, ...)``).

For each window of each run: its candidates (anchored later, in the layer), its odometry pose,
the keyframes it adds to the path since the previous window (the whole window on an odometry
segment's first, in ``head``), its evidence sample, and the flags that start a segment
(``restart``) and end a run (``last``). Sizes are bucketed so that batches share compilations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mfcl_jax.decision import layer

__all__ = ["RunInputs", "run_inputs"]


@dataclass(frozen=True)
class RunInputs:
    """The windows of ``R`` runs as the layer sees them (host arrays, ``(R, K, ...)``)."""

    evidence: layer.WindowEvidence
    n_windows: np.ndarray  # (R,) valid windows per run
    seg_windows: np.ndarray  # (R,) most windows in one odometry segment
    seg_keyframes: np.ndarray  # (R,) most keyframes in one odometry segment


def run_inputs(batch, cands, min_step: int = 16, min_head: int = 0) -> RunInputs:
    """``RunInputs`` of every run of a ``windows.WindowBatch`` and its ``Candidates``.

    ``min_step``, ``min_head``: the least keyframes per window and per segment's first window
    (several batches with the same floors share one compilation)."""
    rb, sub, ev = batch.runs, batch.submaps, batch.evidence
    traj, seg, tmask = (np.asarray(a) for a in (rb.traj, rb.traj_seg, rb.traj_mask))
    ws, we, wm, sm = (np.asarray(a) for a in (rb.window_start, rb.window_end, rb.window_mask,
                                              rb.submap))  # fmt: skip
    R, K = wm.shape
    chunks, starts, restarts, lasts = [], np.zeros((R, K), np.int32), np.zeros((R, K), bool), \
        np.zeros((R, K), bool)  # fmt: skip
    seg_w, seg_t = np.zeros(R, np.int64), np.zeros(R, np.int64)
    n_windows = wm.sum(1)
    for r in range(R):
        prev_seg, prev_end, t0, count = None, -1, 0, 0
        for k in np.flatnonzero(wm[r]):
            s = seg[r, ws[r, k]]
            if s != prev_seg:
                t0 = int(np.flatnonzero((seg[r] == s) & tmask[r])[0])
                prev_end, count = t0 - 1, 0
                restarts[r, k] = True
                seg_t[r] = max(seg_t[r], int(((seg[r] == s) & tmask[r]).sum()))
            count += 1
            seg_w[r] = max(seg_w[r], count)
            chunks.append((r, k, prev_end + 1, int(we[r, k]) + 1))
            starts[r, k] = ws[r, k] - t0
            prev_seg, prev_end = s, int(we[r, k])
        if n_windows[r]:
            lasts[r, np.flatnonzero(wm[r])[-1]] = True
    # Keyframes per window: a few since the previous window, the whole window on a segment's
    # first (whose history is empty: those go to ``head``, which extends no walk).
    S = max([b - a for r, k, a, b in chunks if not restarts[r, k]] + [min_step, 1])
    S = -(-S // 16) * 16
    S0 = max([b - a - S for r, k, a, b in chunks if restarts[r, k]] + [min_head, 0])
    S0 = -(-max(S0, 0) // 16) * 16
    tr = np.zeros((R, K, S, 3), np.float32)
    tm = np.zeros((R, K, S), bool)
    hd = np.zeros((R, K, S0, 3), np.float32)
    hm = np.zeros((R, K, S0), bool)
    for r, k, a, b in chunks:
        n = min(b - a, S)
        tr[r, k, :n], tm[r, k, :n] = traj[r, b - n : b], True
        if b - a > n:
            hd[r, k, : b - a - n], hm[r, k, : b - a - n] = traj[r, a : b - n], True
    idx = np.clip(sm, 0, max(sub.n - 1, 0))
    ok = wm & (sm >= 0)
    evw = layer.WindowEvidence(
        Y=np.asarray(cands.pose)[idx], score=np.asarray(cands.score)[idx],
        mask=np.asarray(cands.mask)[idx] & ok[..., None], X=np.asarray(sub.X)[idx],
        traj=tr, traj_mask=tm, head=hd, head_mask=hm, start=starts,
        ev_points=np.asarray(ev.points)[idx], ev_origins=np.asarray(ev.origins)[idx],
        ev_mask=np.asarray(ev.mask)[idx] & ok[..., None], valid=ok, last=lasts,
        restart=restarts,
        end_points=None if ev.end_points is None else np.asarray(ev.end_points)[idx],
        end_mask=None if ev.end_mask is None else np.asarray(ev.end_mask)[idx] & ok[..., None],
    )  # fmt: skip
    return RunInputs(evw, n_windows, seg_w, seg_t)
