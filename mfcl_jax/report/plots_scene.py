"""Figures of built-in scenes: floor plan, clutter and trajectories (matplotlib, host only)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.patches import PathPatch
from matplotlib.patches import Polygon as MplPolygon
from matplotlib.path import Path as MplPath
from shapely.geometry.polygon import orient

from mfcl_jax.sim.trajectory import TrajectoryParams, sample_path

__all__ = ["plot_family", "draw_floorplan", "draw_scene", "plot_scenes"]

_ROOM_COLOURS = ["#dbe9f6", "#e3f1dc", "#fbe8d3", "#efe0f3", "#f6f3cf", "#d9f0ef"]
_TRAJ_COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"]


def _polys(geom):
    return list(geom.geoms) if hasattr(geom, "geoms") else [geom]


def draw_floorplan(ax, fp, label_rooms: bool = True) -> None:
    """Rooms filled and named, wall solids in dark grey, doors as thick green bars."""
    for i, room in enumerate(fp.rooms):
        xy = np.asarray(room.polygon.exterior.coords)
        ax.add_patch(
            MplPolygon(
                xy, closed=True, fc=_ROOM_COLOURS[i % len(_ROOM_COLOURS)], ec="none", zorder=0
            )
        )
        if label_rooms:
            # Low in the room, on a pale box: the trajectories mostly run through the middle.
            x0, y0, x1, y1 = room.polygon.bounds
            ax.text(
                room.polygon.centroid.x,
                y0 + 0.35 * (y1 - y0),
                room.name,
                ha="center",
                va="center",
                fontsize=13,
                fontweight="bold",
                color="#444444",
                zorder=8,
                bbox=dict(fc="white", ec="none", alpha=0.6, pad=1.5),
            )
    for poly in _polys(fp.wall_solid):
        # A closed building's wall solid has the rooms as holes: draw it as one compound path
        # (exterior counter-clockwise, holes clockwise) so the holes stay transparent.
        poly = orient(poly, 1.0)
        rings = [poly.exterior, *poly.interiors]
        path = MplPath.make_compound_path(
            *[MplPath(np.asarray(r.coords), closed=True) for r in rings]
        )
        ax.add_patch(PathPatch(path, fc="#3a3a3a", ec="#3a3a3a", lw=0.5, zorder=2))
    for door in fp.doors:
        seg = np.asarray(door.segment)
        ax.plot(
            seg[:, 0], seg[:, 1], color="#2e8b57", lw=6, solid_capstyle="butt", zorder=3, alpha=0.8
        )


def draw_scene(ax, scene, params: TrajectoryParams | None = None, title=None) -> None:
    """One scene: floor plan, clutter (orange, not in the plan) and smoothed trajectories."""
    params = TrajectoryParams() if params is None else params
    draw_floorplan(ax, scene.floorplan)
    if len(scene.clutter):
        ax.add_collection(
            LineCollection(
                scene.clutter,
                colors="#e07b00",
                linewidths=1.4,
                zorder=4,
                label="clutter / as-built (not in plan)",
            )
        )
    for i, (name, wp) in enumerate(scene.trajectories.items()):
        path = sample_path(wp, params).poses
        col = _TRAJ_COLOURS[i % len(_TRAJ_COLOURS)]
        ax.plot(
            path[:, 0],
            path[:, 1],
            color=col,
            lw=1.6,
            zorder=5,
            label=f"{name} ({path.shape[0] * params.scan_spacing:.0f} m)",
        )
        step = max(1, len(path) // 10)
        ax.quiver(
            path[::step, 0],
            path[::step, 1],
            np.cos(path[::step, 2]),
            np.sin(path[::step, 2]),
            color=col,
            angles="xy",
            scale_units="xy",
            scale=1.2,
            width=0.0025,
            headwidth=4,
            zorder=6,
        )
        ax.plot(*path[0, :2], "o", ms=9, mfc="white", mec=col, mew=2.2, zorder=7)
        ax.plot(*path[-1, :2], "s", ms=6, color=col, zorder=7)
    ax.set_aspect("equal")
    xmin, ymin, xmax, ymax = scene.floorplan.bounds
    ax.set_xlim(xmin - 1, xmax + 1)
    ax.set_ylim(ymin - 1, ymax + 1)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title or scene.name)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=3, fontsize=8, frameon=False)


def plot_scenes(scenes, out=None):
    """Scenes stacked in one column on a common metre scale; saves to ``out`` if given.

    The buildings are long and narrow (42.6 m x 11.2 m, 29.2 m x 6.4 m), so one above the
    other keeps both legible where a single row would be a thin strip.
    """
    widths = [s.floorplan.bounds[2] - s.floorplan.bounds[0] + 2 for s in scenes]
    heights = [s.floorplan.bounds[3] - s.floorplan.bounds[1] + 2 for s in scenes]
    scale = 16.0 / max(widths)  # inches per metre
    fig, axes = plt.subplots(
        len(scenes),
        1,
        squeeze=False,
        figsize=(17.0, scale * sum(heights) + 2.2 * len(scenes)),
        gridspec_kw={"height_ratios": [h + 4 for h in heights]},
    )
    for ax, scene in zip(axes[:, 0], scenes, strict=True):
        draw_scene(ax, scene, title=f"{scene.name}: {scene.description}")
    fig.tight_layout(h_pad=2.5)
    if out is not None:
        fig.savefig(out, dpi=150, bbox_inches="tight")
    return fig


def plot_family(scene, out_png) -> Path:
    """Draws a scene: the floor plan, the clutter, the real walls where they differ from the
    plan (dashed) and every walk; written atomically.

    Args:
        scene: a ``Scene``.
        out_png: output image path.

    Returns:
        The path of the PNG written.
    """
    import io
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from mfcl_jax.io.atomic import atomic_write

    x0, y0, x1, y1 = scene.floorplan.bounds
    width = 11.0
    fig, ax = plt.subplots(figsize=(width, width * (y1 - y0 + 2.0) / (x1 - x0 + 2.0) + 2.4))
    draw_scene(ax, scene, title="\n".join(textwrap.wrap(f"{scene.name}: {scene.description}", 100)))
    ax.title.set_fontsize(10)
    if scene.as_built is not None:
        ax.add_collection(
            LineCollection(
                scene.as_built,
                colors="#c0008a",
                linewidths=1.0,
                linestyles="--",
                zorder=4,
                label="real walls (as built)",
            )
        )
    # Beside the plan, not below it: long thin buildings leave no room below.
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return atomic_write(Path(out_png), buf.getvalue())
