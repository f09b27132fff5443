"""The study's tables, built with pandas from scored decisions (never typed in).

Every builder takes ``firsts`` (one row per scene x trajectory x d_s x seed x policy, from
``metrics.first_commits``) or the scored per-window table, and returns a DataFrame. Writing
(CSV, Markdown, LaTeX) is ``write_table``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from mfcl_jax.io.atomic import atomic_write
from mfcl_jax.score.summary import wilson

__all__ = [
    "FORCED",
    "policy_table",
    "policy_rates",
    "selective_metrics",
    "ablation",
    "sensitivity",
    "symmetric_sim",
    "write_table",
    "cell",
]

FORCED = ("single_shot", "support", "confidence", "ours")


def cell(row) -> str:
    """A paper-style cell: mark, committed room / planar error, and the window."""
    if not row["committed"]:
        return f"abstain ({row['final_state']})"
    mark = "OK" if row["correct"] else "X"
    return f"{mark} {row['room']}/{row['err_xy']:.2f} (k={int(row['k'])})"


def _rate(x: pd.Series) -> str:
    n, s = len(x), int(np.sum(x))
    lo, hi = wilson(s, n)
    return f"{s}/{n} [{lo:.2f}, {hi:.2f}]" if n else "-"


def policy_table(firsts: pd.DataFrame, seed: int, policies=FORCED) -> pd.DataFrame:
    """Paper Table II for one seed: trajectory x d_s rows, one cell per policy."""
    f = firsts[(firsts["seed"] == seed) & firsts["policy"].isin(policies)]
    rows = []
    for (traj, ds), g in f.groupby(["trajectory", "d_s"], sort=True):
        row = {"trajectory": traj, "d_s": ds}
        for pol in policies:
            r = g[g["policy"] == pol]
            row[pol] = cell(r.iloc[0]) if len(r) else "-"
        rows.append(row)
    out = pd.DataFrame(rows)
    total = {"trajectory": "correct", "d_s": ""}
    for pol in policies:
        r = f[f["policy"] == pol]
        total[pol] = f"{int(r['correct'].sum())}/{len(r)}"
    return pd.concat([out, pd.DataFrame([total])], ignore_index=True)


def policy_rates(firsts: pd.DataFrame, policies=FORCED) -> pd.DataFrame:
    """Per trajectory x d_s x policy over seeds: correct rate with a 95% Wilson interval."""
    f = firsts[firsts["policy"].isin(policies)]
    rows = []
    for (traj, ds, pol), g in f.groupby(["trajectory", "d_s", "policy"], sort=True):
        rows.append(
            {
                "trajectory": traj,
                "d_s": ds,
                "policy": pol,
                "seeds": len(g),
                "correct": _rate(g["correct"]),
                "false_commit": _rate(g["false_commit"]),
                "abstain": _rate(~g["committed"]),
                "median_err_xy": float(np.nanmedian(g["err_xy"]))
                if g["committed"].any()
                else math.nan,
                "mean_k": float(np.nanmean(g["k"])) if g["committed"].any() else math.nan,
            }
        )
    return pd.DataFrame(rows)


def selective_metrics(firsts: pd.DataFrame, policies=FORCED) -> pd.DataFrame:
    """Paper Table III: correct / false commits, abstentions and mean window per policy."""
    rows = []
    for pol in policies:
        g = firsts[firsts["policy"] == pol]
        if not len(g):
            continue
        n = len(g)
        rows.append(
            {
                "policy": pol,
                "configs": n,
                "correct_commit": f"{int(g['correct'].sum())}/{n}",
                "false_commit": f"{int(g['false_commit'].sum())}/{n}",
                "abstain": f"{int((~g['committed']).sum())}/{n}",
                "correct_rate_ci95": _rate(g["correct"]),
                "false_rate_ci95": _rate(g["false_commit"]),
                "mean_commit_k": float(np.nanmean(g["k"])) if g["committed"].any() else math.nan,
            }
        )
    return pd.DataFrame(rows)


def ablation(firsts: pd.DataFrame) -> pd.DataFrame:
    """Gate-only, consensus-only, no-probe, the paper's layer (probe without the scan
    certification) and ours on the same configurations."""
    return selective_metrics(
        firsts, policies=("gate_only", "consensus_only", "no_probe", "paper", "ours")
    )


def sensitivity(firsts: pd.DataFrame) -> pd.DataFrame:
    """Commit floors (b_min, delta_min) in {(2,1), (3,2), (4,2)}."""
    names = {"ours_b2_d1": "(2,1)", "ours": "(3,2)", "ours_b4_d2": "(4,2)"}
    out = selective_metrics(firsts, policies=tuple(names))
    out.insert(1, "floors", out["policy"].map(names))
    return out


def symmetric_sim(scored: pd.DataFrame, pitch: float, seed: int, d_s: float) -> pd.DataFrame:
    """Per-window state and tau for each start of the symmetric scene, ours vs no-probe.

    ``scored`` holds the windows of the symmetric scene; ``bay_multiple`` expresses a committed
    anchor's displacement from the truth in units of the pitch.
    """
    s = scored[(scored["seed"] == seed) & (scored["d_s"] == d_s)]
    s = s[s["policy"].isin(["ours", "no_probe"])]
    rows = []
    for (traj, k), g in s.groupby(["trajectory", "k"], sort=True):
        row = {"trajectory": traj, "k": int(k)}
        for pol, r in g.groupby("policy"):
            r = r.iloc[0]
            tau = math.hypot(r["tau_x"], r["tau_y"]) if np.isfinite(r["tau_x"]) else math.nan
            row[f"{pol}_state"] = r["state"]
            row[f"{pol}_kind"] = r["kind"]
            row[f"{pol}_tau"] = tau
            row[f"{pol}_B1"] = int(r["B1"])
            row[f"{pol}_margin"] = int(r["margin"])
            row[f"{pol}_err_xy"] = r["err_xy"]
            row[f"{pol}_bay_multiple"] = (
                r["err_xy"] / pitch if np.isfinite(r["err_xy"]) else math.nan
            )
        rows.append(row)
    return pd.DataFrame(rows)


def write_table(df: pd.DataFrame, out_dir, name: str, latex: bool = False) -> list[Path]:
    """Writes ``name.csv`` and ``name.md`` (and ``name.tex``) atomically; returns the paths."""
    out_dir = Path(out_dir)
    paths = [out_dir / f"{name}.csv", out_dir / f"{name}.md"]
    atomic_write(paths[0], df.to_csv(index=False, float_format="%.4g"))
    atomic_write(paths[1], df.to_markdown(index=False, floatfmt=".3g") + "\n")
    if latex:
        paths.append(out_dir / f"{name}.tex")
        atomic_write(paths[2], df.to_latex(index=False, float_format="%.3g", escape=True))
    return paths
