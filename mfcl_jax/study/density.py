"""Density immunity (C2) on simulated data: flood the candidate pool, keep every top-1.

At our commit window of one run, every submap's candidate list grows ``factor``-fold by
appending jittered copies of its own non-champion candidates, each scored strictly below the
copied candidate (so below the submap's top-1). Our layer must be unchanged; support-style
head-count may flip.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from mfcl_jax import windows as W
from mfcl_jax.frontend.candidates import Candidates
from mfcl_jax.study.pipeline import StudyData

__all__ = ["subset", "flood", "stack_copies", "density_table"]


def subset(data: StudyData, cands: Candidates, run_ids):
    """The runs ``run_ids`` alone, re-packed, with their candidates.

    Returns:
        ``(batch, recordings, runs, cands)``: a ``WindowBatch`` of those runs, their
        recordings, their rows of ``data.runs`` (renumbered from 0) and their candidates.
    """
    run_ids = [int(r) for r in run_ids]
    b = data.batch
    items = [(data.recordings[r].seq, b.windows[r], int(b.run_building[r])) for r in run_ids]
    batch = W.pack(items, capacity=int(np.asarray(b.submaps.points).shape[1]))
    rows = np.concatenate([np.asarray(b.runs.submap)[r, : len(b.windows[r])] for r in run_ids])
    c = Candidates(
        *(np.asarray(getattr(cands, f))[rows] for f in ("pose", "score", "mask", "reason"))
    )
    runs = data.runs.set_index("run").loc[run_ids].reset_index()
    runs["run"] = np.arange(len(run_ids))
    return batch, [data.recordings[r] for r in run_ids], runs, c


def flood(c: Candidates, factor: int, seed: int = 0, jitter_xy=0.2, jitter_deg=1.0) -> Candidates:
    """Appends ``(factor - 1) * J`` low-weight candidates per submap; no top-1 changes."""
    rng = np.random.default_rng(seed)
    pose, score, mask = (np.asarray(a) for a in (c.pose, c.score, c.mask))
    n, j, _ = pose.shape
    extra = (factor - 1) * j
    new_pose = np.zeros((n, extra, 3), np.float32)
    new_score = np.full((n, extra), -np.inf, np.float32)
    new_mask = np.zeros((n, extra), bool)
    for i in range(n):
        valid = np.flatnonzero(mask[i])
        if len(valid) < 2:
            continue
        top = valid[np.argmax(score[i, valid])]
        pool = valid[valid != top]
        src = pool[np.arange(extra) % len(pool)]
        new_pose[i, :, :2] = pose[i, src, :2] + rng.normal(0, jitter_xy, (extra, 2))
        new_pose[i, :, 2] = pose[i, src, 2] + np.deg2rad(rng.normal(0, jitter_deg, extra))
        new_score[i] = score[i, src] - (0.01 + 0.05 * rng.random(extra)) * (
            1.0 + abs(score[i, top])
        )
        new_mask[i] = True
    return Candidates(
        pose=np.concatenate([pose, new_pose], 1),
        score=np.concatenate([score, new_score], 1),
        mask=np.concatenate([mask, new_mask], 1),
        reason=np.asarray(c.reason),
    )


def stack_copies(a: Candidates, b: Candidates) -> Candidates:
    """The rows of ``a`` then those of ``b``, ``a`` padded with masked candidates to ``b``'s
    count (two copies of one run decided in one batch)."""
    j = np.asarray(b.pose).shape[1]

    def pad(x, fill):
        x = np.asarray(x)
        width = [(0, 0)] * x.ndim
        width[1] = (0, j - x.shape[1])
        return np.pad(x, width, constant_values=fill)

    return Candidates(
        pose=np.concatenate([pad(a.pose, 0.0), np.asarray(b.pose)]),
        score=np.concatenate([pad(a.score, -np.inf), np.asarray(b.score)]),
        mask=np.concatenate([pad(a.mask, False), np.asarray(b.mask)]),
        reason=np.concatenate([np.asarray(a.reason), np.asarray(b.reason)]),
    )


def density_table(
    before: pd.DataFrame,
    after: pd.DataFrame,
    k_star: int,
    pool_before: int,
    pool_after: int,
    policies=("ours", "support"),
) -> pd.DataFrame:
    """Before/after rows at window ``k_star`` for each policy."""
    rows = []
    for label, df, pool in (("original", before, pool_before), ("flooded", after, pool_after)):
        for pol in policies:
            g = df[(df["policy"] == pol)].sort_values("k")
            r = g[g["k"] == k_star].iloc[0]
            com = g[g["state"] == "COMMIT"]
            rows.append(
                {
                    "policy": pol,
                    "pool": label,
                    "candidates_to_k": pool,
                    "state_at_k": r["state"],
                    "first_commit_k": int(com["k"].iloc[0]) if len(com) else np.nan,
                    "room": r["room"],
                    "x": r["x"],
                    "y": r["y"],
                    "yaw_deg": r["yaw_deg"],
                    "B1": int(r["B1"]),
                    "margin": int(r["margin"]),
                    "err_xy": r["err_xy"],
                }
            )
    return pd.DataFrame(rows)
