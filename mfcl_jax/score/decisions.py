"""Scoring decisions against ground truth: the one scorer, the only code that reads it.

A decision at time ``t`` with anchor ``T*`` places the robot at ``T* X(t)``, ``X(t)`` the
odometry pose at ``t``; it is compared with the true pose at ``t``. Both are looked up by
time in the odometry / ground-truth tables (exact match within 1 ms, otherwise linear
interpolation between the bracketing lines; a time outside the table is an error).
A placement is correct within ``CORRECT_XY`` m and ``CORRECT_YAW_DEG`` deg (no room test:
the study, the benchmark and ``mfcl evaluate`` share this one definition). The room names
of the placed and the true pose are reported alongside when a floor plan is given.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from mfcl_jax import se2
from mfcl_jax.io.errors import DataError
from mfcl_jax.score.summary import CORRECT_XY, CORRECT_YAW_DEG

__all__ = [
    "pose_at",
    "decisions_frame",
    "score_rows",
    "score_decisions",
    "score_batch",
    "summarize",
    "segment_summaries",
    "format_table",
]


def pose_at(times, poses, t, where: str = "<poses>") -> np.ndarray:
    """Poses ``(n, 3)`` at times ``t (n,)`` (exact within 1 ms, else interpolated)."""
    times = np.asarray(times, np.float64)
    poses = np.asarray(poses, np.float64)
    t = np.atleast_1d(np.asarray(t, np.float64))
    lo, hi = times[0] - 1e-3, times[-1] + 1e-3
    bad = (t < lo) | (t > hi) | ~np.isfinite(t)
    if bad.any():
        raise DataError(f"{where}: decision time t={t[bad][0]} outside [{times[0]}, {times[-1]}]")
    yaw = np.unwrap(poses[:, 2])
    out = np.stack(
        [
            np.interp(t, times, poses[:, 0]),
            np.interp(t, times, poses[:, 1]),
            np.interp(t, times, yaw),
        ],
        -1,
    )
    j = np.clip(np.searchsorted(times, t), 0, len(times) - 1)
    j = np.where(
        (j > 0) & (np.abs(times[np.maximum(j - 1, 0)] - t) < np.abs(times[j] - t)), j - 1, j
    )
    exact = np.abs(times[j] - t) < 1e-3
    out[exact] = poses[j[exact]]
    out[:, 2] = se2.wrap_host(out[:, 2])
    return out


def decisions_frame(decisions) -> pd.DataFrame:
    """A decisions JSON-lines log (``io.read_decisions``) as a table in time order: ``k, t,
    segment, state, symmetry, B1, B2, margin, x, y, yaw_deg`` (anchor NaN when none) and
    ``pose_x, pose_y, pose_yaw_deg`` (the robot's pose the line gives; NaN when none) and
    ``storey`` (the storey a commit names in a plan of several; None otherwise).

    Rows are ordered by ``t`` (lines with equal times keep the file's order), never by ``k``:
    a file written before ``k`` counted over the whole recording starts ``k`` again at 1
    after an odometry jump. ``segment`` is the file's; in a file without it (written before
    ``mfcl localize`` reported segments) a new segment starts wherever ``k`` does not grow.
    """
    rows = []
    for d in decisions:
        a = d["anchor"] or {}
        pose = d.get("pose") or {}
        rows.append(
            dict(
                k=int(d["k"]),
                t=d["t"],
                segment=d.get("segment"),
                state=d["state"],
                symmetry=d["symmetry"],
                B1=d["B1"],
                B2=d["B2"],
                margin=d["margin"],
                x=a.get("x", math.nan),
                y=a.get("y", math.nan),
                yaw_deg=a.get("yaw_deg", math.nan),
                pose_x=pose.get("x", math.nan),
                pose_y=pose.get("y", math.nan),
                pose_yaw_deg=pose.get("yaw_deg", math.nan),
                storey=d.get("storey"),
            )
        )
    cols = ["k", "t", "segment", "state", "symmetry", "B1", "B2", "margin", "x", "y", "yaw_deg",
            "pose_x", "pose_y", "pose_yaw_deg", "storey"]  # fmt: skip
    df = pd.DataFrame(rows, columns=cols)
    if df.empty:
        return df.astype({"segment": np.int64})
    df = df.sort_values("t", kind="stable").reset_index(drop=True)
    if df["segment"].isna().any():  # k starts again after a jump in such files
        df["segment"] = np.concatenate([[0], np.cumsum(np.diff(df["k"].to_numpy()) <= 0)])
    return df.astype({"segment": np.int64})


def _errors(df, cols, X, Y):
    """``(has, placed, err_xy, err_yaw_rad)`` of the anchors in columns ``cols`` (x, y,
    yaw in degrees; NaN: none) at odometry poses ``X`` against the truth ``Y``."""
    A = df[list(cols)].to_numpy(np.float64, copy=True)
    A[:, 2] = np.deg2rad(A[:, 2])
    has = np.all(np.isfinite(A), 1)
    placed = se2.compose_host(np.where(has[:, None], A, 0.0), X)
    dxy = np.hypot(placed[:, 0] - Y[:, 0], placed[:, 1] - Y[:, 1])
    dth = np.abs(se2.wrap_host(placed[:, 2] - Y[:, 2]))
    return has, placed, dxy, dth


def score_rows(
    df: pd.DataFrame, odom_times, odom, gt_times, gt, floorplan=None, where: str = "<decisions>"
) -> pd.DataFrame:
    """Adds placement errors to decision rows (columns ``k, t, x, y, yaw_deg``).

    Args:
        df: one row per decision; ``x, y, yaw_deg`` the anchor ``^B T_L`` (NaN: none).
        odom_times, odom: ``(N,)``, ``(N, 3)`` odometry in L.
        gt_times, gt: ``(M,)``, ``(M, 3)`` true sensor poses in B.
        floorplan: optional, adds the placed and true room names.

    Returns:
        A copy with ``err_xy, err_yaw_deg, correct`` (NaN / False without an anchor), with
        ``test_correct`` where ``df`` has the uniqueness test's placement (``test_x``, ...),
        ``true_x, true_y, placed_x, placed_y`` and, with a floor plan, ``room, true_room``.
    """
    df = df.copy()
    if df.empty:
        return df.assign(err_xy=[], err_yaw_deg=[], correct=[])
    if df["t"].isna().any():
        raise DataError(f"{where}: decision k={int(df.loc[df['t'].isna(), 'k'].iloc[0])} has no t")
    t = df["t"].to_numpy(np.float64)
    X = pose_at(odom_times, odom, t, f"{where} (odometry)")
    Y = pose_at(gt_times, gt, t, f"{where} (ground truth)")
    has, placed, dxy, dth = _errors(df, ("x", "y", "yaw_deg"), X, Y)
    if "pose_x" in df:
        # the pose a robot reads is judged too (the worse of the two errors is reported)
        P = df[["pose_x", "pose_y", "pose_yaw_deg"]].to_numpy(np.float64, copy=True)
        has_pose = np.all(np.isfinite(P), 1)
        p_xy = np.hypot(P[:, 0] - Y[:, 0], P[:, 1] - Y[:, 1])
        p_th = np.abs(se2.wrap_host(np.deg2rad(P[:, 2]) - Y[:, 2]))
        dxy = np.where(has_pose, np.fmax(dxy, p_xy), dxy)
        dth = np.where(has_pose, np.fmax(dth, p_th), dth)
    df["err_xy"] = np.where(has, dxy, np.nan)
    df["err_yaw_deg"] = np.where(has, np.degrees(dth), np.nan)
    df["correct"] = has & (df["err_xy"] < CORRECT_XY) & (df["err_yaw_deg"] < CORRECT_YAW_DEG)
    if "test_x" in df:
        # the uniqueness test's own placement, judged by the same line (NaN: not tested)
        t_has, _, t_xy, t_th = _errors(df, ("test_x", "test_y", "test_yaw_deg"), X, Y)
        ok = (t_xy < CORRECT_XY) & (np.degrees(t_th) < CORRECT_YAW_DEG)
        df["test_correct"] = pd.Series(ok, index=df.index).astype("boolean").mask(~t_has)
    df["true_x"], df["true_y"] = Y[:, 0], Y[:, 1]
    df["placed_x"] = np.where(has, placed[:, 0], np.nan)
    df["placed_y"] = np.where(has, placed[:, 1], np.nan)
    if floorplan is not None:
        df["room"] = [
            r if h else None for r, h in zip(floorplan.room_at(placed[:, :2]), has, strict=True)
        ]
        df["true_room"] = floorplan.room_at(Y[:, :2])
    return df


def score_decisions(
    decisions, odom_times, odom, gt_times, gt, floorplan=None, where: str = "<decisions>"
) -> pd.DataFrame:
    """Scores a decisions JSON-lines log (``decisions_frame`` + ``score_rows``)."""
    return score_rows(decisions_frame(decisions), odom_times, odom, gt_times, gt, floorplan, where)


def score_batch(frame: pd.DataFrame, batch, recordings, rooms: bool = True) -> pd.DataFrame:
    """Scores a decision table of a ``WindowBatch`` (``decision.frame.decide``'s frame).

    Window ``k`` of run ``r`` is decided at the time of its last scan; every run is scored
    against the odometry the layer used (its windows' keyframe odometry) and its recording's
    ground truth by ``score_rows``.

    Args:
        frame: rows with ``run``, ``k`` (1-based), ``x, y, yaw_deg``.
        batch: the ``WindowBatch`` the decisions were made on.
        recordings: the runs' ``Recording``s, in the batch's run order (with ``truth``).
        rooms: add the placed and true room names.
    """
    parts = []
    for r, g in frame.groupby("run", sort=True):
        rec = recordings[int(r)]
        if rec.truth is None:
            raise DataError(f"{rec.name}: no ground truth to score against")
        w = batch.windows[int(r)]
        g = g.assign(t=w.t[g["k"].to_numpy() - 1])
        fp = rec.floorplan if rooms else None
        # The anchors are of the layer's odometry (``Windows.odometry``, LiDAR-refined where
        # enabled), so that odometry places the robot.
        kt = np.asarray(rec.seq.times)[w.keyframes]
        s = score_rows(g, kt, w.odometry, rec.truth.times, rec.truth.poses, fp, rec.name)
        parts.append(_storey_rule(s, rec.floorplan))
    return pd.concat(parts) if parts else frame.iloc[:0]


def _storey_rule(scored: pd.DataFrame, floorplan) -> pd.DataFrame:
    """On a plan of several storeys (``floorplan.storeys``), an anchor that places the robot
    on a place several congruent storeys share names no storey: not correct, wherever the
    truth is (the truth of a walk on any of them lies there too)."""
    st = getattr(floorplan, "storeys", None)
    if st is None or not len(scored) or "placed_x" not in scored:
        return scored
    xy = scored[["placed_x", "placed_y"]].to_numpy(np.float64)
    tiles = [st.tile_at(x, y) if np.isfinite(x) else -1 for x, y in xy]
    shared = np.array([t >= 0 and st.shared(t) for t in tiles])
    return scored.assign(correct=scored["correct"].to_numpy(bool) & ~shared)


def summarize(scored: pd.DataFrame) -> dict:
    """First commit and end state of one scored run, in time order (``t``: the first
    commit is the earliest, the final state the latest window's).

    Returns:
        ``windows, first_commit_k, first_commit_t, err_xy, err_yaw_deg, correct,
        false_commit, final_state, final_symmetry, commits, commits_correct``.
    """
    out = dict(
        windows=len(scored),
        first_commit_k=None,
        first_commit_t=None,
        err_xy=math.nan,
        err_yaw_deg=math.nan,
        correct=None,
        false_commit=False,
        final_state=None,
        final_symmetry=None,
        commits=0,
        commits_correct=0,
    )
    if scored.empty:
        return out
    s = scored.sort_values("t", kind="stable") if "t" in scored else scored.sort_values("k")
    last = s.iloc[-1]
    out["final_state"] = last["state"]
    out["final_symmetry"] = last["symmetry"] if isinstance(last["symmetry"], str) else None
    com = s[s["state"] == "COMMIT"]
    out["commits"] = len(com)
    if "correct" in s:
        out["commits_correct"] = int(com["correct"].sum())
    if len(com):
        c = com.iloc[0]
        out.update(first_commit_k=int(c["k"]), first_commit_t=float(c["t"]))
        if "err_xy" in c:
            out.update(
                err_xy=float(c["err_xy"]),
                err_yaw_deg=float(c["err_yaw_deg"]),
                correct=bool(c["correct"]),
                false_commit=not bool(c["correct"]),
            )
    return out


def segment_summaries(scored: pd.DataFrame) -> list[dict]:
    """``summarize`` of each odometry segment of a scored run (column ``segment``), in
    order, each with ``segment``, ``k_first, k_last`` and ``t_first, t_last``."""
    out = []
    for seg, g in scored.groupby("segment", sort=True):
        g = g.sort_values("t", kind="stable")
        row = dict(segment=int(seg), k_first=int(g["k"].iloc[0]), k_last=int(g["k"].iloc[-1]),
                   t_first=float(g["t"].iloc[0]), t_last=float(g["t"].iloc[-1]))  # fmt: skip
        out.append(row | summarize(g))
    return out


def format_table(df: pd.DataFrame, floatfmt: str = ".2f", missingval: str = "") -> str:
    """A plain-text table (tabulate) of a small frame (``None`` cells as ``missingval``)."""
    from tabulate import tabulate

    return tabulate(df, headers="keys", tablefmt="github", showindex=False, floatfmt=floatfmt,
                    missingval=missingval)  # fmt: skip
