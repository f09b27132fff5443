"""Run-level summaries of scored decisions: first commits, correctness bounds, intervals."""

from __future__ import annotations

import math

import pandas as pd

__all__ = ["CORRECT_XY", "CORRECT_YAW_DEG", "first_commits", "wilson"]

# A commit is correct within 1 m (the paper's criterion) and 5 deg (ARCHITECTURE.md).
CORRECT_XY = 1.0
CORRECT_YAW_DEG = 5.0


def first_commits(scored: pd.DataFrame, keys=("run", "policy")) -> pd.DataFrame:
    """One row per ``keys`` group: the first COMMIT (or an abstention row).

    Returns:
        Columns: ``keys``, ``committed`` (bool), ``k`` (first commit window, NaN if none),
        ``err_xy``, ``err_yaw_deg``, ``room``, ``true_room``, ``correct``, ``false_commit`` (the
        first commit is wrong), ``commits``, ``commits_wrong``, ``any_false`` (some COMMIT
        window is wrong), ``final_state`` (the state at the last window), ``n_windows``.
    """
    rows = []
    for key, g in scored.sort_values("k").groupby(list(keys), sort=True):
        key = key if isinstance(key, tuple) else (key,)
        row = dict(zip(keys, key, strict=True))
        com = g[g["state"] == "COMMIT"]
        row["final_state"] = g["state"].iloc[-1]
        row["n_windows"] = int(g["k"].max())
        row["commits"] = len(com)
        # A commit must stay right while it is reported: any wrong COMMIT window counts.
        row["commits_wrong"] = int((~com["correct"].astype(bool)).sum()) if len(com) else 0
        if len(com):
            c = com.iloc[0]
            row.update(
                committed=True,
                k=int(c["k"]),
                err_xy=float(c["err_xy"]),
                err_yaw_deg=float(c["err_yaw_deg"]),
                room=c.get("room"),
                true_room=c.get("true_room"),
                correct=bool(c["correct"]),
            )
        else:
            row.update(
                committed=False,
                k=math.nan,
                err_xy=math.nan,
                err_yaw_deg=math.nan,
                room=None,
                true_room=g["true_room"].iloc[-1] if "true_room" in g else None,
                correct=False,
            )
        row["false_commit"] = row["committed"] and not row["correct"]
        row["any_false"] = row["commits_wrong"] > 0
        rows.append(row)
    return pd.DataFrame(rows)


def wilson(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score 95% interval for a rate ``successes / n`` (``(nan, nan)`` when n == 0)."""
    if n == 0:
        return (math.nan, math.nan)
    p = successes / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, centre - half), min(1.0, centre + half))
