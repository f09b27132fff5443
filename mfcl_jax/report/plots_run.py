"""A scored run on its floor plan: the true path, the odometry placed by the first commit
(green when correct, red when false), the commits and the start (``mfcl evaluate --plot``
and the real-data study's figures)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from mfcl_jax.io.atomic import atomic_write
from mfcl_jax.report.plots_floorplan import draw_floorplan

__all__ = ["FORMATS", "DPI", "figure_size", "draw_run", "plot_run"]

FORMATS = (".png", ".pdf", ".svg")
DPI = 100
WIDTH = 8.0  # inches


def figure_size(fp) -> tuple[float, float]:
    """``(width, height)`` in inches of ``plot_run``'s figure: the plan's aspect, the height
    kept within 3.5 and 12 inches."""
    x0, y0, x1, y1 = fp.bounds
    return WIDTH, float(min(max(WIDTH * (y1 - y0) / max(x1 - x0, 1e-6), 3.5), 12.0))


def _colour(ok) -> str:
    return "tab:green" if bool(ok) else "tab:red"


def _include(ax, xy) -> None:
    """Widens the axis limits (set to the plan by ``draw_floorplan``) to hold ``xy``: a
    false placement off the plan stays in the picture."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    xy = xy[np.all(np.isfinite(xy), 1)]
    if not len(xy):
        return
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    pad = 0.03 * max(x1 - x0, y1 - y0)
    lo, hi = xy.min(0), xy.max(0)
    ax.set_xlim(min(x0, lo[0] - pad), max(x1, hi[0] + pad))
    ax.set_ylim(min(y0, lo[1] - pad), max(y1, hi[1] + pad))


def draw_run(ax, fp, truth, odometry, scored, name: str, offset=None) -> None:
    """Draws one scored run into a matplotlib axis.

    Args:
        ax: the axis.
        fp: the ``Floorplan``.
        truth: ``(M, 3)`` true poses (``x, y, yaw``) in the data's frame.
        odometry: ``(N, 3)`` the input odometry the anchors refer to.
        scored: ``score.score_decisions``'s table (``k, state, x, y, yaw_deg, correct,
            placed_x, placed_y, true_x, true_y``, ``symmetry``).
        name: the run's name, for the title.
        offset: ``(2,)`` where the data lie: plan = local + offset (default the plan's own
            ``offset``: decisions files and datasets are in the plan's file frame; ``(0, 0)``
            for data in the plan's local frame).
    """
    from mfcl_jax import se2

    off = np.asarray(fp.offset if offset is None else offset, np.float64)
    draw_floorplan(
        ax, fp.transformed((off[0], off[1], 0.0)) if off.any() else fp, labels=False, graph=False
    )
    truth = np.asarray(truth, np.float64).reshape(-1, 3)
    if len(truth):
        ax.plot(truth[:, 0], truth[:, 1], "-", color="k", lw=1.2, label="true path")
        ax.plot(truth[0, 0], truth[0, 1], "^", color="k", ms=7, label="start")
    com = scored[scored["state"] == "COMMIT"] if len(scored) else scored
    if len(com):
        c = com.iloc[0]
        A = np.array([c["x"], c["y"], np.deg2rad(c["yaw_deg"])])
        placed = se2.compose_host(A, np.asarray(odometry, np.float64))
        ok = bool(c["correct"])
        ax.plot(
            placed[:, 0],
            placed[:, 1],
            "--",
            color=_colour(ok),
            lw=1.2,
            label=f"odometry placed by the first commit (k={int(c['k'])}, "
            f"{'correct' if ok else 'FALSE'})",
        )
        ax.scatter(
            com["placed_x"],
            com["placed_y"],
            s=9,
            zorder=8,
            c=[_colour(v) for v in com["correct"]],
            label="robot at each commit",
        )
        ax.plot(
            c["placed_x"],
            c["placed_y"],
            "o",
            color=_colour(ok),
            ms=8,
            zorder=9,
            label="first commit",
        )
        ax.plot(c["true_x"], c["true_y"], "x", color="k", ms=8, zorder=9, label="truth then")
        _include(ax, placed[:, :2])
    _include(ax, truth[:, :2])
    end = "no windows"
    if len(scored):
        last = scored.iloc[-1]
        sym = last["symmetry"]
        end = f"final {last['state']}" + (f" ({sym})" if isinstance(sym, str) else "")
    first = f"first commit k={int(com.iloc[0]['k'])}" if len(com) else "no commit"
    ax.set_title(f"{name}: {len(scored)} windows, {first}, {end}", fontsize=9)
    ax.legend(fontsize=7, loc="best")


def plot_run(out, fp, truth, odometry, scored, name: str, offset=None) -> Path:
    """``draw_run`` into a figure of ``figure_size(fp)`` at ``DPI``, written atomically to
    ``out`` (its suffix one of ``FORMATS``); returns the path.

    Raises:
        DataError: an unsupported suffix; an output that cannot be written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mfcl_jax.io.errors import DataError

    out = Path(out)
    if out.suffix.lower() not in FORMATS:
        raise DataError(f"{out}: unknown figure type {out.suffix!r}; use one of {FORMATS}")
    fig, ax = plt.subplots(figsize=figure_size(fp))
    buf = io.BytesIO()
    try:
        draw_run(ax, fp, truth, odometry, scored, name, offset)
        fig.tight_layout()
        fig.savefig(buf, format=out.suffix.lower()[1:], dpi=DPI)
    finally:
        plt.close(fig)
    return atomic_write(out, buf.getvalue())
