"""The benchmark's figures: risk-coverage curves, commits against metres travelled, and one
figure per fault axis (drawn from its tables; ``bench.main`` saves them)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

__all__ = [
    "risk_coverage_figure",
    "commit_distance_figure",
    "risk_distance_figure",
    "fault_figure",
    "save",
    "DISTANCE_POLICIES",
]

STYLE = {
    "ours": dict(color="tab:green", marker="o", lw=2.2),
    "paper": dict(color="black", marker="d", ls="--"),
    "no_probe": dict(color="tab:olive", marker="v"),
    "consensus_only": dict(color="tab:cyan", marker="^"),
    "ours_b2_d1": dict(color="tab:green", marker="<", ls=":"),
    "ours_b4_d2": dict(color="tab:green", marker=">", ls=":"),
    "single_shot": dict(color="tab:red", marker="s"),
    "support": dict(color="tab:orange", marker="D"),
    "confidence": dict(color="tab:purple", marker="P"),
    "gate_only": dict(color="tab:brown", marker="X"),
    "mcl": dict(color="tab:blue", marker="*", lw=2.0),
    "ours_unique": dict(color="tab:pink", marker="o", ls="-."),
    "ours_unique_a1": dict(color="tab:pink", marker="v", ls=":"),
    "ours_unique_a2": dict(color="tab:pink", marker="<", ls=":"),
    "ours_unique_a4": dict(color="tab:pink", marker=">", ls=":"),
    "ours_unique_a6": dict(color="tab:pink", marker="^", ls=":"),
}


def save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def risk_coverage_figure(rc: pd.DataFrame, title: str = ""):
    """False-commit rate (y) against coverage of identifiable runs (x), one curve per policy."""
    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    for pol, g in rc.groupby("policy", sort=False):
        g = g.sort_values("coverage")
        ax.plot(g["coverage"], g["false_rate"], label=pol, ms=5, **STYLE.get(pol, {}))
    ax.set_xlabel("coverage: correct commits / identifiable runs")
    ax.set_ylabel("risk: runs with a false commit / runs")
    ax.set_xlim(-0.02, 1.02)
    ax.set_ylim(bottom=-0.01)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    ax.set_title(title or "risk vs coverage (each point: one knob setting)", fontsize=10)
    return fig


# The policies of the distance figure (those present): our layer, two uniqueness lanes (1e-3,
# 1e-1), the paper's layer, the particle filter.
DISTANCE_POLICIES = ("ours", "ours_unique", "ours_unique_a1", "ours_grid", "paper", "mcl")


def _cumulative(ax, metres, n: int, x_end: float, label: str, style: dict) -> None:
    """Step curve of the share of ``n`` runs with a value of ``metres`` at or below x, drawn
    from 0 to ``x_end``."""
    m = np.sort(np.asarray(metres, np.float64))
    m = m[np.isfinite(m)]
    x = np.concatenate([[0.0], m, [max(x_end, m[-1] if len(m) else 0.0)]])
    y = np.concatenate([np.arange(len(m) + 1), [len(m)]]) / max(n, 1)
    ax.step(x, y, where="post", label=label, **{k: v for k, v in style.items() if k != "marker"})


def commit_distance_figure(runs: pd.DataFrame, policies=DISTANCE_POLICIES):
    """Cumulative share of runs committed correctly (left: of the identifiable runs, by the
    metres of the first commit, ``commit_m``) and falsely (right: of all runs, by the metres of
    the first wrong COMMIT window, ``false_m``) against the metres travelled; nominal runs at
    the default thresholds, for the ``DISTANCE_POLICIES`` among ``policies`` (all of
    ``policies`` when none is). The curves end at the coverage and the false-commit rate."""
    from mfcl_jax.report.benchmark import nominal

    nom = nominal(runs)
    present = [p for p in policies if p in set(nom["policy"])]
    shown = [p for p in present if p in DISTANCE_POLICIES] or present
    ends = nom.loc[nom["policy"].isin(shown), ["commit_m", "false_m"]].to_numpy(np.float64)
    x_end = float(np.nanmax(ends)) * 1.05 if np.isfinite(ends).any() else 1.0
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2), sharex=True)
    for pol in shown:
        g = nom[nom["policy"] == pol]
        ident = g["identifiable"].astype(bool)
        st = STYLE.get(pol, {})
        right = g.loc[g["correct_run"].astype(bool) & ident, "commit_m"]
        n_id = int(ident.sum())
        _cumulative(a1, right, n_id, x_end, f"{pol} ({len(right)}/{n_id})", st)
        wrong = g.loc[g["any_false"].astype(bool), "false_m"]
        _cumulative(a2, wrong, len(g), x_end, f"{pol} ({len(wrong)}/{len(g)})", st)
    a1.set_ylabel("correct commits / identifiable runs")
    a2.set_ylabel("runs with a false commit / runs")
    a1.set_title("committed correctly by x metres (first commit)", fontsize=10)
    a2.set_title("committed falsely by x metres (first wrong commit)", fontsize=10)
    for a in (a1, a2):
        a.set_xlabel("metres travelled (odometry, from the run's start)")
        a.set_ylim(-0.02, 1.02)
        a.set_xlim(left=0.0)
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    return fig


def risk_distance_figure(overall: pd.DataFrame):
    """Risk against distance, one point per policy of the ``overall`` table (nominal runs,
    default thresholds): the false-commit rate (y) against the median metres travelled to the
    first correct commit (x), coverage in the legend. The price of committing earlier reads as
    a move up and to the left."""
    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    for _, r in overall.iterrows():
        if not np.isfinite(r["median_commit_m"]):
            continue
        st = {k: v for k, v in STYLE.get(r["policy"], {}).items() if k in ("color", "marker")}
        rate = r["n_false"] / max(r["runs"], 1)
        cov = r["n_covered"] / max(r["identifiable"], 1)
        ax.plot(r["median_commit_m"], rate, ls="none", ms=8, alpha=0.8,
                label=f"{r['policy']} (coverage {cov:.0%})", **(st or {"marker": "o"}))  # fmt: skip
    ax.set_xlabel("median metres travelled to the first correct commit")
    ax.set_ylabel("risk: runs with a false commit / runs")
    ax.set_ylim(bottom=-0.01)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax.set_title("risk against distance (nominal runs, default thresholds)", fontsize=10)
    return fig


def fault_figure(table: pd.DataFrame, axis: str, levels):
    """False-commit rate and coverage against the level of one fault axis (its ``levels``, in
    order), per policy."""
    levels = [str(v) for v in levels]
    # the levels at evenly spaced positions, labelled (strings as x data make matplotlib log a
    # line per call about numbers read as categories)
    x = np.arange(len(levels))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.0))
    for pol, g in table.groupby("policy", sort=False):
        g = g.set_index("level").reindex(levels)
        st = STYLE.get(pol, {})
        a1.plot(x, g["n_false"] / g["runs"], label=pol, **st)
        a2.plot(x, g["n_covered"] / g["identifiable"].where(g["identifiable"] > 0), **st)
    a1.set_ylabel("runs with a false commit / runs")
    a2.set_ylabel("correct commits / identifiable runs")
    for a in (a1, a2):
        a.set_xticks(x, levels)
        a.set_xlabel(axis)
        a.grid(alpha=0.3)
    a1.legend(fontsize=8, ncol=2)
    fig.suptitle(f"fault axis: {axis}", fontsize=10)
    return fig
