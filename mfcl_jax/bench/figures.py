"""Benchmark figures: risk-coverage curves and one figure per fault axis."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from mfcl_jax.bench.config import FAULTS  # noqa: E402

__all__ = ["risk_coverage_figure", "fault_figure", "save"]

STYLE = {
    "ours": dict(color="tab:green", marker="o", lw=2.2),
    "no_probe": dict(color="tab:olive", marker="v"),
    "consensus_only": dict(color="tab:cyan", marker="^"),
    "ours_b2_d1": dict(color="tab:green", marker="<", ls=":"),
    "ours_b4_d2": dict(color="tab:green", marker=">", ls=":"),
    "single_shot": dict(color="tab:red", marker="s"),
    "support": dict(color="tab:orange", marker="D"),
    "confidence": dict(color="tab:purple", marker="P"),
    "gate_only": dict(color="tab:brown", marker="X"),
    "mcl": dict(color="tab:blue", marker="*", lw=2.0),
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


def fault_figure(table: pd.DataFrame, axis: str):
    """False-commit rate and coverage against the level of one fault axis, per policy."""
    levels = [str(v) for v in FAULTS[axis]]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.0))
    for pol, g in table.groupby("policy", sort=False):
        g = g.set_index("level").reindex(levels)
        st = STYLE.get(pol, {})
        a1.plot(levels, g["n_false"] / g["runs"], label=pol, **st)
        a2.plot(levels, g["n_covered"] / g["identifiable"].where(g["identifiable"] > 0), **st)
    a1.set_ylabel("runs with a false commit / runs")
    a2.set_ylabel("correct commits / identifiable runs")
    for a in (a1, a2):
        a.set_xlabel(axis)
        a.grid(alpha=0.3)
    a1.legend(fontsize=8, ncol=2)
    fig.suptitle(f"fault axis: {axis}", fontsize=10)
    return fig
