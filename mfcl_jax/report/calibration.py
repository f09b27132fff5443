"""How much room the right commits had: the uniqueness test's ratio against what the layer
reported, window by window, and the commit margins.

Commit margins (``commit_margins``): how close the COMMIT windows came to the line between a
right and a false commit (``CORRECT_XY`` m, ``CORRECT_YAW_DEG``), per family. Zero false
commits on the benchmark say little about a building we have never seen if the right ones
passed at 0.9 of the line; this table says how much room there was.

The test (``decision.uniqueness``) compares the best placement of the whole path with the best
one outside its neighbourhood: ``llr = L(A*) - L(competitor)``. Under its observation model a
wrong placement reaches a ratio ``llr`` against the truth with probability at most
``exp(-llr)`` (Wald's bound), so a lane with error rate ``alpha`` commits at
``llr >= log(1 / alpha)``. This table checks the model where it matters: in every window where
the test ran and no veto held, was ``A*`` (the placement a lane commits to when the test holds,
``test_correct``) right or wrong, binned by the ratio. A wrong ``A*`` in a bin above a lane's
threshold is a false commit that lane would have made or did make. Tables written before
``A*`` was recorded judge the layer's reported anchor instead (``correct``: the window's
champion, within the grouping tolerance of ``A*`` by a veto, or the commit itself), which can
be wrong by a few degrees where ``A*``, fitted to the whole path, is not.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from mfcl_jax.score.summary import CORRECT_XY, CORRECT_YAW_DEG

__all__ = [
    "EDGES",
    "LANE_ALPHAS",
    "GRID_MARGINS",
    "ratio_calibration",
    "fault_level_calibration",
    "commit_margins",
    "grid_calibration",
]

# the uniqueness lanes' error rates, by the suffix of their column in ``fault_level_calibration``
LANE_ALPHAS = {"a1": 1e-1, "a2": 1e-2, "a3": 1e-3, "a4": 1e-4, "a6": 1e-6}
# bin edges: 1, 2, 3 nats and the lanes' thresholds log(1 / alpha) (2.30 ... 13.8 nats)
EDGES = tuple(sorted({0.0, 1.0, 2.0, 3.0, *(math.log(1 / a) for a in LANE_ALPHAS.values())})) + (
    math.inf,
)


def _tested(windows: pd.DataFrame, policy: str):
    """The windows where ``policy``'s test ran unvetoed and was judged, and which were wrong."""
    judged = "test_correct" if "test_correct" in windows else "correct"
    w = windows[(windows["policy"] == policy) & windows["llr"].notna()]
    w = w[(w["llr"] > -np.inf) & w[judged].notna()]
    return w, ~w[judged].astype(bool)


def ratio_calibration(windows: pd.DataFrame, policy: str = "ours_unique_a6") -> pd.DataFrame:
    """Per ratio bin: tested windows and wrong anchors, nominal runs and fault rows apart.

    Args:
        windows: the benchmark's per-window table (``windows.csv.gz``: ``policy, fault, llr,
            test_correct`` or, in older tables, ``correct``).
        policy: the lane read (the test is shared by the uniqueness lanes; ``alpha = 1e-6``
            keeps testing longest, as it commits last).

    Returns:
        One row per bin ``[llr_from, llr_to)``: ``bound`` (``exp(-llr_from)``, the model's
        bound for one wrong placement), ``windows`` and ``wrong`` (nominal: windows tested
        unvetoed and judged, and of them the anchor past the false-commit line),
        ``fault_windows`` and ``fault_wrong`` (the same over the fault rows).
    """
    w, wrong = _tested(windows, policy)
    fault = w["fault"].fillna("").astype(str) != ""
    rows = []
    for lo, hi in zip(EDGES[:-1], EDGES[1:], strict=True):
        b = (w["llr"] >= lo) & (w["llr"] < hi) if hi < math.inf else w["llr"] >= lo
        rows.append(dict(
            llr_from=round(lo, 2), llr_to=round(hi, 2), bound=math.exp(-lo),
            windows=int((b & ~fault).sum()), wrong=int((b & ~fault & wrong).sum()),
            fault_windows=int((b & fault).sum()), fault_wrong=int((b & fault & wrong).sum()),
        ))  # fmt: skip
    return pd.DataFrame(rows)


def fault_level_calibration(windows: pd.DataFrame, policy: str = "ours_unique_a6") -> pd.DataFrame:
    """The bound checked at every level of every fault axis: per (axis, level), the windows
    where the test ran unvetoed and was judged, and for each lane's threshold
    ``log(1 / alpha)`` the windows at or above it and how many of those had a wrong ``A*``.

    A wrong window at or above a lane's threshold is a false commit that lane made or would
    have made (the lane commits at the first such window of a run; later windows of the run
    count too). Windows of one run are not independent: the counts say where the bound was
    broken, not a rate to compare with ``alpha`` digit by digit.

    Args:
        windows: the benchmark's per-window table (``fault, level, policy, llr`` and
            ``test_correct``, or ``correct`` in older tables).
        policy: the lane read (see ``ratio_calibration``).

    Returns:
        One row per ``(fault, level)``, the nominal runs first (``fault = "nominal"``), then
        every fault level in axis order, then ``all fault rows``: ``windows``, ``wrong`` (any
        ratio) and ``windows_<a>``, ``wrong_<a>`` for each lane of ``LANE_ALPHAS``.
    """
    w, wrong = _tested(windows, policy)
    fault = w["fault"].fillna("").astype(str)
    level = w["level"].fillna("").astype(str) if "level" in w else pd.Series("", index=w.index)

    def row(name, lev, sel):
        out = dict(fault=name, level=lev, windows=int(sel.sum()), wrong=int((sel & wrong).sum()))
        for a, alpha in LANE_ALPHAS.items():
            past = sel & (w["llr"] >= math.log(1 / alpha))
            out[f"windows_{a}"] = int(past.sum())
            out[f"wrong_{a}"] = int((past & wrong).sum())
        return out

    rows = [row("nominal", "", fault == "")]
    for name, lev in dict.fromkeys(zip(fault[fault != ""], level[fault != ""], strict=True)):
        rows.append(row(name, lev, (fault == name) & (level == lev)))
    if (fault != "").any():
        rows.append(row("all fault rows", "", fault != ""))
    return pd.DataFrame(rows)


def commit_margins(windows: pd.DataFrame, policy: str = "ours") -> pd.DataFrame:
    """Per family (nominal runs), then all nominal runs and all fault rows: the COMMIT windows
    of ``policy`` at the default thresholds and how close the right ones came to the line.

    Args:
        windows: the benchmark's per-window table (``windows.csv.gz``: ``name, family, fault,
            policy, state, err_xy, err_yaw_deg``).
        policy: the policy reported.

    Returns:
        One row per group: ``commit_windows``, ``wrong`` (COMMIT windows past the line),
        ``max_xy_m`` and ``max_yaw_deg`` (largest error among the right ones), ``use`` (the
        largest share of the line used by a right one: ``max(err_xy / CORRECT_XY, err_yaw /
        CORRECT_YAW_DEG)``), ``over_half`` (right ones past half the line) and ``runs`` with a
        commit.
    """
    w = windows[(windows["policy"] == policy) & (windows["state"] == "COMMIT")].copy()
    w["fault"] = w["fault"].fillna("").astype(str)
    w["use"] = np.maximum(w["err_xy"] / CORRECT_XY, w["err_yaw_deg"] / CORRECT_YAW_DEG)

    def row(group: str, g: pd.DataFrame) -> dict:
        right = g[g["use"] <= 1.0]
        return dict(
            group=group,
            runs=len(g.drop_duplicates([c for c in ("name", "fault", "level") if c in g])),
            commit_windows=len(g),
            wrong=int((g["use"] > 1.0).sum()),
            max_xy_m=float(right["err_xy"].max()) if len(right) else math.nan,
            max_yaw_deg=float(right["err_yaw_deg"].max()) if len(right) else math.nan,
            use=float(right["use"].max()) if len(right) else math.nan,
            over_half=int((right["use"] > 0.5).sum()),
        )

    nom = w[w["fault"] == ""]
    rows = [row(fam, g) for fam, g in nom.groupby("family", sort=False)]
    rows.append(row("all nominal", nom))
    rows.append(row("all fault rows", w[w["fault"] != ""]))
    return pd.DataFrame(rows)


# the evidence grid's margins tried (nats of its pooled model, ``decision.grid``)
GRID_MARGINS = (2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0)


def grid_calibration(windows: pd.DataFrame, policy: str = "ours_grid_off",
                     margins=GRID_MARGINS) -> pd.DataFrame:  # fmt: skip
    """What a grid lane would do at each commit margin, read off a lane that never commits on
    the grid (``policy``: it records the grid's margin at every window until its count rule
    commits).

    Per margin and per row group (nominal runs; every fault row; each fault axis), over the
    runs: ``runs``, ``false`` (runs whose first window at or past the margin, unvetoed, had a
    wrong anchor: a false commit that lane would make; the Wilson interval beside it),
    ``committed`` (runs committed right, at that window or by the count rule), ``median_m``
    (median metres travelled at the first right commit of identifiable runs) and
    ``windows``/``wrong`` (every unvetoed window at or past the margin, and the wrong ones).
    """
    from mfcl_jax.score.summary import wilson

    judged = "test_correct" if "test_correct" in windows else "correct"
    w = windows[windows["policy"] == policy].copy()
    w["fault"] = w["fault"].fillna("").astype(str)
    w["level"] = w["level"].fillna("").astype(str) if "level" in w else ""
    w = w.sort_values(["run", "k"])
    tested = w["llr"].notna() & (w["llr"] > -np.inf) & w[judged].notna()
    wrong = tested & ~w[judged].fillna(True).astype(bool)
    groups = [("nominal", w["fault"] == ""), ("all fault rows", w["fault"] != "")]
    groups += [(f"fault {a}", w["fault"] == a) for a in dict.fromkeys(w["fault"][w["fault"] != ""])]
    rows = []
    for m in margins:
        past = tested & (w["llr"] >= m)
        for name, sel in groups:
            g = w[sel]
            if g.empty:
                continue
            n_false = n_right = 0
            metres = []
            for _, r in g.groupby(["run", "fault", "level"], sort=False):
                cross = r[past.loc[r.index]]
                count = r[r["state"] == "COMMIT"]
                first = min([x["k"].iloc[0] for x in (cross, count) if len(x)], default=None)
                if first is None:
                    continue
                at = r[r["k"] == first].iloc[0]
                bad = bool(wrong.loc[at.name]) if len(cross) and cross["k"].iloc[0] == first \
                    else not bool(at["correct"])  # fmt: skip
                n_false += bad
                n_right += not bad
                if not bad and r["ident_k"].astype(bool).any():
                    metres.append(float(at["metres"]))
            runs = g.groupby(["run", "fault", "level"], sort=False).ngroups
            lo, hi = wilson(n_false, runs)
            rows.append(dict(margin=m, group=name, runs=runs, false=n_false,
                             false_upper=round(hi, 3), committed=n_right,
                             median_m=round(float(np.median(metres)), 1) if metres else np.nan,
                             windows=int((past & sel).sum()),
                             wrong=int((past & sel & wrong).sum())))  # fmt: skip
    return pd.DataFrame(rows)
