"""Pictures of log-window recordings: the held-out map, the window's true path and its scans.

The window's own scans, placed by the ground truth, are drawn over the map that was built
without them: where they land on the map's walls, the map is an honest prior for the window;
where they land in unknown space, the window saw a place nothing else in the log saw.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from mfcl_jax import se2

__all__ = ["draw_log_recording", "plot_log_recording"]


def draw_log_recording(ax, rec, max_scans: int = 120) -> None:
    """Draws one recording into a matplotlib axis.

    Args:
        ax: the axis.
        rec: a ``Recording`` with ground truth (a log or bag window).
        max_scans: at most this many of the window's scans are drawn (evenly thinned).
    """
    from mfcl_jax.report.plots_floorplan import draw_floorplan

    fp, truth = rec.floorplan, rec.truth
    draw_floorplan(ax, fp, labels=False, graph=False)
    pick = np.unique(np.linspace(0, len(rec.seq) - 1, min(max_scans, len(rec.seq))).astype(int))
    # Truth is on the sequence's clock: take the true pose of each drawn scan by its time.
    j = np.clip(np.searchsorted(truth.times, rec.seq.times[pick]), 0, len(truth.times) - 1)
    pts = [
        np.asarray(se2.apply(truth.poses[k], rec.seq.scans[i]), np.float64)
        for i, k in zip(pick, j, strict=True)
        if len(rec.seq.scans[i])
    ]
    if pts:
        p = np.concatenate(pts)
        ax.scatter(p[:, 0], p[:, 1], s=0.3, color="tab:orange", alpha=0.5, zorder=3, lw=0)
    xy = truth.poses[:, :2]
    ax.plot(xy[:, 0], xy[:, 1], "-", color="k", lw=1.2, zorder=5, label="true path")
    ax.plot(*xy[0], "^", color="k", ms=6, zorder=6, label="start")
    ax.plot([], [], ".", color="tab:orange", label="window scans (not in map)")
    # The path may leave the map (places only the window saw): show all of it.
    x0, y0, x1, y1 = fp.bounds
    lo = np.minimum([x0, y0], xy.min(0) - 1.0)
    hi = np.maximum([x1, y1], xy.max(0) + 1.0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    m = rec.meta
    ax.set_title(
        f"{rec.name}: {m.get('travel_m', float('nan')):.0f} m, {len(rec.seq)} scans, "
        f"map {m.get('map_res', float('nan')):.2f} m, {len(fp.rooms)} rooms, "
        f"path on free cells {m.get('map_coverage', float('nan')):.0%}",
        fontsize=8,
    )
    ax.legend(fontsize=6, loc="best")


def plot_log_recording(rec, out_png) -> Path:
    """Writes a picture of one recording, or of several side by side (a list), to a PNG.

    Args:
        rec: a ``Recording`` or a sequence of them.
        out_png: output path; written atomically.

    Returns:
        The path of the written image.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    recs = list(rec) if isinstance(rec, list | tuple) else [rec]
    x0, y0, x1, y1 = recs[0].floorplan.bounds
    aspect = min(max((y1 - y0) / max(x1 - x0, 1e-6), 0.3), 2.0)
    w = 6.5
    fig, axes = plt.subplots(1, len(recs), figsize=(w * len(recs), w * aspect + 0.8), squeeze=False)
    for ax, r in zip(axes[0], recs, strict=True):
        draw_log_recording(ax, r)
    out = Path(out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.stem}.", suffix=".png")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=130, bbox_inches="tight")
        os.replace(tmp, out)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out
