"""Scoring decisions against ground truth (the only place ground truth is used).

A decision's anchor ``T*`` places the robot at window k as ``T* X_k`` (``X_k`` is the odometry
pose of the window's last scan). It is scored against the true pose at that instant: planar
error, yaw error, and the room the robot is placed in versus the room it is truly in.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from mfcl_jax import se2

__all__ = ["CORRECT_XY", "CORRECT_YAW_DEG", "score_windows", "first_commits", "wilson"]

# A commit is correct when it is in the right room and within 1 m (the paper's criterion);
# the yaw bound follows the dataset-level check of ARCHITECTURE.md (1 m / 5 deg).
CORRECT_XY = 1.0
CORRECT_YAW_DEG = 5.0


def score_windows(dec: pd.DataFrame, runs_batch, submaps, truth, floorplans: dict) -> pd.DataFrame:
    """Adds truth columns to a per-window decision table.

    Args:
        dec: rows with columns ``run``, ``k`` (1-based), ``x``, ``y``, ``yaw`` (rad; NaN when the
            row has no anchor) and ``scene``.
        runs_batch: the ``RunBatch`` the decisions were computed on.
        submaps: the ``SubmapBatch`` (for ``X``).
        truth: the ``Truth``.
        floorplans: scene name -> ``Floorplan`` (for room names).

    Returns:
        ``dec`` with ``err_xy``, ``err_yaw_deg``, ``room``, ``true_room``, ``correct`` added.
    """
    dec = dec.copy()
    sub_idx = np.asarray(runs_batch.submap)[dec["run"].to_numpy(), dec["k"].to_numpy() - 1]
    end_idx = np.asarray(runs_batch.window_end)[dec["run"].to_numpy(), dec["k"].to_numpy() - 1]
    X = np.asarray(submaps.X)[sub_idx]
    true_pose = np.asarray(truth.traj)[dec["run"].to_numpy(), end_idx]
    anchor = dec[["x", "y", "yaw"]].to_numpy(dtype=np.float64)
    has = np.all(np.isfinite(anchor), axis=1)
    placed = np.asarray(se2.compose(np.where(has[:, None], anchor, 0.0), X), dtype=np.float64)
    dxy, dth = (np.asarray(v) for v in se2.distance_pair(placed, true_pose))
    dec["err_xy"] = np.where(has, dxy, np.nan)
    dec["err_yaw_deg"] = np.where(has, np.degrees(dth), np.nan)
    rooms, true_rooms = [], []
    for scene, idx in dec.groupby("scene").groups.items():
        pos = dec.index.get_indexer(idx)
        fp = floorplans[scene]
        r = fp.room_at(placed[pos, :2])
        tr = fp.room_at(true_pose[pos, :2])
        rooms.extend(zip(pos, r, strict=True))
        true_rooms.extend(zip(pos, tr, strict=True))
    room = np.empty(len(dec), object)
    true_room = np.empty(len(dec), object)
    for p, r in rooms:
        room[p] = r if has[p] else None
    for p, r in true_rooms:
        true_room[p] = r
    dec["room"] = room
    dec["true_room"] = true_room
    # The room check applies where both placements fall in a named room: in a doorway the
    # robot is in no room, and then the metric bounds alone decide.
    both_named = np.array(
        [r is not None and t is not None for r, t in zip(room, true_room, strict=True)]
    )
    wrong_room = both_named & (dec["room"].to_numpy() != dec["true_room"].to_numpy())
    dec["correct"] = (
        has
        & ~wrong_room
        & (dec["err_xy"].to_numpy() < CORRECT_XY)
        & (dec["err_yaw_deg"].to_numpy() < CORRECT_YAW_DEG)
    )
    return dec


def first_commits(scored: pd.DataFrame, keys=("run", "policy")) -> pd.DataFrame:
    """One row per ``keys`` group: the first COMMIT (or an abstention row).

    Returns:
        Columns: ``keys``, ``committed`` (bool), ``k`` (first commit window, NaN if none),
        ``err_xy``, ``err_yaw_deg``, ``room``, ``true_room``, ``correct``, ``false_commit``,
        ``final_state`` (the state at the last window).
    """
    rows = []
    for key, g in scored.sort_values("k").groupby(list(keys), sort=True):
        key = key if isinstance(key, tuple) else (key,)
        row = dict(zip(keys, key, strict=True))
        com = g[g["state"] == "COMMIT"]
        row["final_state"] = g["state"].iloc[-1]
        row["n_windows"] = int(g["k"].max())
        if len(com):
            c = com.iloc[0]
            row.update(
                committed=True,
                k=int(c["k"]),
                err_xy=float(c["err_xy"]),
                err_yaw_deg=float(c["err_yaw_deg"]),
                room=c["room"],
                true_room=c["true_room"],
                correct=bool(c["correct"]),
            )
        else:
            row.update(
                committed=False,
                k=math.nan,
                err_xy=math.nan,
                err_yaw_deg=math.nan,
                room=None,
                true_room=g["true_room"].iloc[-1],
                correct=False,
            )
        row["false_commit"] = row["committed"] and not row["correct"]
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
