"""Benchmark tables and figures, from the scored decisions and the geometric labels.

Per run and policy (threshold set ``DEFAULT_SET`` unless stated):

* a FALSE commit run: some COMMIT window places the robot wrong (> 1 m or > 5 deg); a commit
  must stay right while it is reported, so a run that committed correctly and later drifted
  off counts as false;
* a CORRECT commit run: it committed and every COMMIT window is right;
* coverage: correct commit runs / identifiable runs; abstention: runs without a commit /
  non-identifiable runs; rates carry Wilson 95 % intervals;
* delay: first commit window minus the oracle window (identifiable runs committed correctly);
* distance (``commit_m``, ``oracle_m``, ``false_m``, ``delay_m``): metres travelled by the end
  of the first commit window, of the oracle window and of the first wrong COMMIT window, by the
  run's own input odometry over its keyframes from its first keyframe (``bench.run.window_metres``:
  the distance the windows are cut by; an odometry quantity). A run split by an odometry
  restart counts from the run's start, the jump itself counting nothing. ``delay_m`` is
  ``commit_m - oracle_m`` for the runs ``delay`` is given for; the tables' ``median_commit_m``
  and ``median_delay_m`` are medians over the same runs as ``median_delay``;
The margins of the right commits and the ratio calibration: ``report.calibration``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from mfcl_jax.bench.config import FAULTS
from mfcl_jax.bench.run import DEFAULT_SET, KNOB_SETS
from mfcl_jax.score import first_commits, wilson

__all__ = [
    "run_table",
    "nominal",
    "family_table",
    "family_matrix",
    "risk_coverage",
    "label_strength",
    "fault_table",
    "first_false_level",
]


def run_table(scored: pd.DataFrame, labels) -> pd.DataFrame:
    """One row per run x policy x set: first commit, correctness, the run's label."""
    keys = ("run", "policy", "set")
    fc = first_commits(scored, keys)
    meta_cols = [c for c in ("name", "family", "source", "seed", "walk", "fault", "level")
                 if c in scored]  # fmt: skip
    meta = scored.drop_duplicates("run")[["run", *meta_cols]]
    lab = pd.DataFrame(
        dict(
            run=np.arange(len(labels)),
            identifiable=[lb.identifiable for lb in labels],
            oracle_k=[lb.oracle_k if lb.oracle_k is not None else math.nan for lb in labels],
            n_alternatives=[lb.n_alternatives for lb in labels],
            label_strength=[lb.strength for lb in labels],
        )
    )
    out = fc.merge(meta, on="run", how="left").merge(lab, on="run", how="left")
    out["correct_run"] = out["committed"] & ~out["any_false"]
    ok = out["correct_run"] & out["identifiable"]
    out["delay"] = np.where(ok, out["k"] - out["oracle_k"], np.nan)
    if "metres" in scored:
        at = _metres_lookup(scored)
        com = scored[scored["state"] == "COMMIT"]
        wrong = com[~com["correct"].astype(bool)].groupby(list(keys))["k"].min()
        false_k = wrong.reindex(pd.MultiIndex.from_frame(out[list(keys)])).to_numpy()
        out["commit_m"] = at(out["run"], out["k"])
        out["oracle_m"] = at(out["run"], out["oracle_k"])
        out["false_m"] = at(out["run"], false_k)
        out["delay_m"] = np.where(ok, out["commit_m"] - out["oracle_m"], np.nan)
    return out


def _metres_lookup(scored: pd.DataFrame):
    """``at(run, k)``: the ``metres`` column of window ``k`` of ``run`` (NaN where ``k`` is)."""
    w = scored.drop_duplicates(["run", "k"])
    key = zip(w["run"].astype(int), w["k"].astype(int), strict=True)
    table = dict(zip(key, w["metres"], strict=True))

    def at(run, k) -> np.ndarray:
        return np.asarray(
            [
                table.get((int(r), int(kk)), math.nan) if np.isfinite(kk) else math.nan
                for r, kk in zip(run, np.asarray(k, np.float64), strict=True)
            ],
            np.float64,
        )

    return at


def _rate(k: int, n: int) -> str:
    if n == 0:
        return "-"
    lo, hi = wilson(k, n)
    return f"{k}/{n} [{lo:.2f}, {hi:.2f}]"


def _summary(g: pd.DataFrame) -> dict:
    n = len(g)
    ident = g["identifiable"].astype(bool)
    false = int(g["any_false"].sum())
    cov = int((g["correct_run"] & ident).sum())
    abst = int((~g["committed"] & ~ident).sum())
    lucky = int((g["correct_run"] & ~ident).sum())
    delay = g.loc[g["correct_run"] & ident, "delay"]
    err = g.loc[g["correct_run"], "err_xy"]

    def median_m(col: str) -> float:  # over the runs of median_delay; NaN in older runs.csv
        m = g.loc[g["correct_run"] & ident, col].dropna() if col in g else []
        return float(m.median()) if len(m) else math.nan

    return dict(
        runs=n,
        identifiable=int(ident.sum()),
        n_false=false,
        n_covered=cov,
        false_commit=_rate(false, n),
        false_upper=wilson(false, n)[1] if n else math.nan,
        coverage=_rate(cov, int(ident.sum())),
        abstain_nonident=_rate(abst, int((~ident).sum())),
        lucky_commits=lucky,
        median_delay=float(delay.median()) if len(delay) else math.nan,
        median_err_m=float(err.median()) if len(err) else math.nan,
        median_commit_m=median_m("commit_m"),
        median_delay_m=median_m("delay_m"),
    )


def nominal(runs: pd.DataFrame) -> pd.DataFrame:
    """The nominal rows (no fault) at the default threshold set."""
    return runs[(runs["fault"].fillna("") == "") & (runs["set"] == DEFAULT_SET)]


def family_table(runs: pd.DataFrame, policies, by: str = "family") -> pd.DataFrame:
    """Per ``by`` value and policy (nominal runs, default set), plus an ``all`` row each."""
    nom = nominal(runs)
    rows = []
    for pol in policies:
        g = nom[nom["policy"] == pol]
        if g.empty:
            continue
        for fam, gf in g.groupby(by, sort=False):
            rows.append({by: fam, "policy": pol, **_summary(gf)})
        rows.append({by: "all", "policy": pol, **_summary(g)})
    return pd.DataFrame(rows)


CLEAR = 2.0  # a run identified at twice the labeller's thresholds or more is "clear"


def label_strength(runs: pd.DataFrame, policies) -> pd.DataFrame:
    """Coverage by how clearly the labeller identified a run (nominal runs, default set):
    ``marginal`` runs rest on a contradiction of at most ``CLEAR`` times its thresholds
    (``score.identifiability``: 1.04 is 6 of 192 rays through a wall in three scans),
    ``clear`` runs on more. Empty when some identifiable run has no strength (a ``runs.csv``
    from before the column, alone or merged with newer ones): a split of part of the runs
    would read as one of all of them."""
    nom = nominal(runs)
    ident = nom["identifiable"].astype(bool)
    if "label_strength" not in nom or nom.loc[ident, "label_strength"].isna().any():
        return pd.DataFrame()
    rows = []
    for pol in policies:
        g = nom[nom["policy"] == pol]
        if g.empty:
            continue
        ident = g["identifiable"].astype(bool)
        clear = ident & (g["label_strength"] > CLEAR)
        ok = g["correct_run"].astype(bool)
        rows.append(dict(
            policy=pol, identifiable=int(ident.sum()), marginal=int((ident & ~clear).sum()),
            marginal_covered=int((ok & ident & ~clear).sum()), clear=int(clear.sum()),
            clear_covered=int((ok & clear).sum()),
            coverage=_rate(int((ok & ident).sum()), int(ident.sum())),
            coverage_clear=_rate(int((ok & clear).sum()), int(clear.sum())),
        ))  # fmt: skip
    return pd.DataFrame(rows)


def family_matrix(table: pd.DataFrame, by: str = "family") -> pd.DataFrame:
    """A ``family_table`` as one row per family and one cell per policy:
    ``false/runs`` false-commit runs, then ``covered/identifiable`` correct commits."""
    cell = table.assign(
        cell=[
            f"{f}/{n} · {c}/{i}"
            for f, n, c, i in zip(
                table["n_false"],
                table["runs"],
                table["n_covered"],
                table["identifiable"],
                strict=True,
            )
        ]  # fmt: skip
    )
    out = cell.pivot(index=by, columns="policy", values="cell")
    out = out.reindex(
        index=list(dict.fromkeys(table[by])), columns=list(dict.fromkeys(table["policy"]))
    )
    return out.reset_index()


def risk_coverage(runs: pd.DataFrame, policies) -> pd.DataFrame:
    """False-commit rate vs coverage of identifiable runs, per policy and knob setting."""
    nom = runs[runs["fault"].fillna("") == ""]
    rows = []
    for (pol, s), g in nom.groupby(["policy", "set"], sort=True):
        if pol not in policies:
            continue
        ident = g["identifiable"].astype(bool)
        n_id = max(int(ident.sum()), 1)
        knob = KNOB_SETS[int(s)] if 0 <= int(s) < len(KNOB_SETS) else {}
        rows.append(
            dict(
                policy=pol,
                set=int(s),
                knob=_knob_label(pol, knob, g),
                runs=len(g),
                false_rate=float(g["any_false"].mean()),
                false_upper=wilson(int(g["any_false"].sum()), len(g))[1],
                coverage=float((g["correct_run"] & ident).sum() / n_id),
                commit_rate=float(g["committed"].mean()),
            )
        )
    return pd.DataFrame(rows)


def _knob_label(pol: str, knob: dict, g) -> str:
    if pol == "ours":
        return (
            f"b_min={knob.get('b_min')}, delta_min={knob.get('delta_min')}, "
            f"margin={knob.get('cert_margin')}"
        )
    if pol in ("paper", "no_probe", "consensus_only"):
        return f"b_min={knob.get('b_min')}, delta_min={knob.get('delta_min')}"
    if pol == "confidence":
        return f"ratio={knob.get('confidence_ratio')}"
    if pol == "support":
        return f"ratio={knob.get('support_ratio')}"
    if "knob" in g:
        return str(g["knob"].iloc[0])
    return "-"


def fault_table(runs: pd.DataFrame, axis: str, policies) -> pd.DataFrame:
    """Per level of one fault axis and policy: false commits / runs, coverage, abstentions."""
    g = runs[(runs["fault"] == axis) & (runs["set"] == DEFAULT_SET)]
    rows = []
    for pol in policies:
        for lvl in FAULTS[axis]:
            h = g[(g["policy"] == pol) & (g["level"] == str(lvl))]
            if h.empty:
                continue
            rows.append({"axis": axis, "level": str(lvl), "policy": pol, **_summary(h)})
    return pd.DataFrame(rows)


def first_false_level(runs: pd.DataFrame, policies) -> pd.DataFrame:
    """Per fault axis and policy: the first level at which some run commits falsely."""
    rows = []
    for axis in FAULTS:
        g = runs[(runs["fault"] == axis) & (runs["set"] == DEFAULT_SET)]
        if g.empty:
            continue
        row = {"axis": axis}
        for pol in policies:
            h = g[g["policy"] == pol]
            bad = [str(lv) for lv in FAULTS[axis] if h[h["level"] == str(lv)]["any_false"].any()]
            row[pol] = bad[0] if bad else "none"
        rows.append(row)
    return pd.DataFrame(rows)
