"""The study's figures (matplotlib, PNG), drawn from scored tables after all jitted work."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from mfcl_jax import se2  # noqa: E402
from mfcl_jax.report.plots_scene import draw_floorplan  # noqa: E402
from mfcl_jax.report.tables import FORCED  # noqa: E402

__all__ = ["state_timeline", "commit_clouds", "anchor_space", "risk_coverage", "save"]

STATE_COLOURS = {"DEFER": "0.65", "AMBIGUOUS": "#f0a020", "COMMIT": "#2ca02c"}


def save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=130, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


def state_timeline(scored: pd.DataFrame, pitch: float, title: str):
    """State vs window k for each start of the symmetric scene, ours and no-probe; tau overlaid."""
    trajs = sorted(scored["trajectory"].unique())
    pols = ["ours", "no_probe"]
    fig, axes = plt.subplots(len(trajs), 1, figsize=(9, 2.6 * len(trajs)), squeeze=False)
    for ax, traj in zip(axes[:, 0], trajs, strict=True):
        ax2 = ax.twinx()
        for row, pol in enumerate(pols):
            g = scored[(scored["trajectory"] == traj) & (scored["policy"] == pol)].sort_values("k")
            for _, r in g.iterrows():
                ax.barh(
                    row, 1.0, left=r["k"] - 0.5, color=STATE_COLOURS[r["state"]], edgecolor="white"
                )
            tau = np.hypot(g["tau_x"], g["tau_y"])
            ax2.plot(
                g["k"],
                tau,
                "o-" if pol == "ours" else "x--",
                color="k" if pol == "ours" else "0.4",
                ms=4,
                lw=1,
                label=f"|tau| ({pol})",
            )
            com = g[g["state"] == "COMMIT"]
            if len(com):
                k0 = com["k"].iloc[0]
                err = com["err_xy"].iloc[0]
                ax.text(
                    k0 - 0.4,
                    row,
                    f"commit k={k0}: {err:.2f} m ({err / pitch:.2f} bays)",
                    fontsize=7,
                    ha="left",
                    va="center",
                    color="white",
                    fontweight="bold",
                )
        ax2.axhline(pitch, color="tab:blue", lw=0.8, ls=":", label=f"pitch {pitch:.2f} m")
        ax2.set_ylim(0, pitch * 2.2)
        ax2.set_ylabel("|tau| (m)")
        ax.set_yticks(range(len(pols)), pols)
        ax.set_ylim(-0.6, len(pols) - 0.1)
        ax.set_xlabel("window k")
        ax.set_title(f"{title}: {traj}", fontsize=9)
        handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in STATE_COLOURS.values()]
        ax.legend(
            handles, list(STATE_COLOURS), loc="upper left", bbox_to_anchor=(1.08, 1.0), fontsize=7
        )
        ax2.legend(loc="lower left", bbox_to_anchor=(1.08, 0.0), fontsize=7)
    fig.tight_layout()
    return fig


def commit_clouds(panels, floorplan):
    """Submap clouds placed by each policy's committed anchor at its commit window.

    Args:
        panels: list of dicts with ``title``, and per policy ``(label, points_B (n, 2), colour,
            err)`` entries under ``clouds``, and ``truth_xy`` (the true robot position).
        floorplan: the building.
    """
    fig, axes = plt.subplots(len(panels), 1, figsize=(11, 3.6 * len(panels)), squeeze=False)
    for ax, panel in zip(axes[:, 0], panels, strict=True):
        draw_floorplan(ax, floorplan)
        for label, pts, colour, err in panel["clouds"]:
            if pts is None:
                continue
            ax.scatter(
                pts[:, 0], pts[:, 1], s=0.6, color=colour, alpha=0.6, label=f"{label} ({err:.2f} m)"
            )
        tx, ty = panel["truth_xy"]
        ax.plot(tx, ty, marker="P", color="k", ms=9, ls="none", label="true position")
        ax.set_title(panel["title"], fontsize=9)
        leg = ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
        for h in leg.legend_handles:
            if hasattr(h, "set_sizes"):
                h.set_sizes([25.0])
        ax.set_aspect("equal")
    fig.tight_layout()
    return fig


def anchor_space(H, score, top1, true_anchor, t_star, title):
    """Candidate anchors, per-window champions and the committed anchor in (x, y) anchor space.

    Args:
        H: ``(n, 3)`` all valid candidate anchors of the run; ``score``: ``(n,)``.
        top1: ``(K, 3)`` each window's champion anchor (front-end top-1).
        true_anchor: ``(3,)`` the true anchor at the first window (scoring only).
        t_star: ``(3,)`` or None, our committed anchor.
    """
    fig, ax = plt.subplots(figsize=(6.5, 5))
    s = np.asarray(score)
    s = (s - s.min()) / max(np.ptp(s), 1e-9)
    ax.scatter(H[:, 0], H[:, 1], s=4 + 20 * s, color="0.75", label="all candidates")
    k = np.arange(len(top1))
    sc = ax.scatter(
        top1[:, 0],
        top1[:, 1],
        c=k + 1,
        cmap="viridis",
        s=36,
        edgecolor="k",
        lw=0.4,
        label="champions (window colour)",
    )
    fig.colorbar(sc, ax=ax, label="window k")
    ax.plot(*true_anchor[:2], marker="P", color="red", ms=11, ls="none", label="true anchor")
    if t_star is not None and np.all(np.isfinite(t_star)):
        ax.plot(
            *t_star[:2], marker="*", color="tab:green", ms=14, ls="none", mec="k", label="our T*"
        )
    ax.set_xlabel("anchor x (m)")
    ax.set_ylabel("anchor y (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="best")
    ax.set_aspect("equal", adjustable="datalim")
    return fig


def risk_coverage(firsts: pd.DataFrame, policies=FORCED + ("gate_only", "no_probe")):
    """Coverage (share of runs with a commit) against risk (false commits per commit)."""
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for scene, marker in zip(sorted(firsts["scene"].unique()), "os^D", strict=False):
        f = firsts[firsts["scene"] == scene]
        for i, pol in enumerate(policies):
            g = f[f["policy"] == pol]
            if not len(g):
                continue
            cov = g["committed"].mean()
            risk = g["false_commit"].sum() / max(g["committed"].sum(), 1)
            ax.scatter(cov, risk, marker=marker, s=60, color=f"C{i}", edgecolor="k", lw=0.4)
            ax.annotate(
                f"{pol}", (cov, risk), fontsize=6, xytext=(4, 3), textcoords="offset points"
            )
    handles = [
        plt.Line2D([], [], marker=m, ls="none", color="0.5", label=s)
        for s, m in zip(sorted(firsts["scene"].unique()), "os^D", strict=False)
    ]
    ax.legend(handles=handles, fontsize=7, loc="upper left")
    ax.set_xlabel("coverage (runs with a commit)")
    ax.set_ylabel("risk (false commits / commits)")
    ax.set_xlim(-0.05, 1.08)
    ax.set_ylim(-0.05, 1.05)
    ax.grid(alpha=0.3)
    ax.set_title("Selective risk vs coverage, all seeds", fontsize=9)
    return fig


def place_submap(points_s, mask, anchor, X):
    """Submap points (frame S) placed in B by an anchor: ``T* X p``."""
    pose = np.asarray(se2.compose(np.asarray(anchor, float), np.asarray(X, float)))
    pts = np.asarray(points_s)[np.asarray(mask)]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return pts @ np.array([[c, s], [-s, c]]) + pose[:2]
