"""Pictures of a floor plan: walls, named rooms, doors and the room graph."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import shapely

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.io.atomic import atomic_write

__all__ = ["draw_floorplan", "show_floorplan"]


def _patch(ax, poly, **kw):
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MPath

    for p in shapely.get_parts(poly):
        if p.is_empty or p.geom_type != "Polygon":
            continue
        rings = [np.asarray(p.exterior.coords)[:, :2]] + [
            np.asarray(r.coords)[:, :2] for r in p.interiors
        ]
        verts = np.concatenate(rings)
        codes = np.concatenate(
            [[MPath.MOVETO] + [MPath.LINETO] * (len(r) - 2) + [MPath.CLOSEPOLY] for r in rings]
        )
        ax.add_patch(PathPatch(MPath(verts, codes), **kw))


def draw_floorplan(ax, fp: Floorplan, labels: bool = True, graph: bool = True) -> None:
    """Draws a floor plan into a matplotlib axis (rooms filled, walls black, doors red)."""
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("tab20")
    # Rooms joined by a door never share a colour (when the graph allows: degree < 20); among
    # the free colours the least used one, so that the picture uses all twenty.
    colour: list[int] = []
    used = np.zeros(20, int)
    for i in range(len(fp.rooms)):
        taken = {colour[j] for j in np.flatnonzero(fp.adjacency[i, :i])}
        free = [c for c in range(20) if c not in taken] or list(range(20))
        colour.append(min(free, key=lambda c: (used[c], c)))
        used[colour[-1]] += 1
    for room, c in zip(fp.rooms, colour, strict=True):
        face = cmap((2 * c + (c // 10)) % 20)  # the ten strong tab20 colours first
        _patch(ax, room.polygon, facecolor=face, alpha=0.45, edgecolor="none", zorder=1)
    _patch(ax, fp.wall_solid, facecolor="0.1", edgecolor="0.1", linewidth=0.3, zorder=2)
    for d in fp.doors:
        s = np.asarray(d.segment)
        ax.plot(s[:, 0], s[:, 1], color="red", linewidth=2.0, zorder=4, solid_capstyle="butt")
    if graph and len(fp.rooms) > 1:
        cen = np.asarray([r.polygon.representative_point().coords[0] for r in fp.rooms])
        adj = fp.adjacency
        for a, b in zip(*np.nonzero(np.triu(adj, 1)), strict=True):
            ax.plot(*cen[[a, b]].T, color="tab:blue", linewidth=0.8, alpha=0.8, zorder=5)
        ax.scatter(cen[:, 0], cen[:, 1], s=6, color="tab:blue", zorder=6)
    if labels:
        size = max(3.0, 8.0 - 0.04 * len(fp.rooms))
        for room in fp.rooms:
            p = room.polygon.representative_point()
            ax.text(p.x, p.y, room.name, fontsize=size, ha="center", va="bottom", zorder=7)
    ax.set_aspect("equal")
    x0, y0, x1, y1 = fp.bounds
    pad = 0.03 * max(x1 - x0, y1 - y0, 1.0)
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def show_floorplan(path_or_floorplan, out_png, storey=None, title: str | None = None) -> Path:
    """Renders a floor plan (a ``Floorplan`` or any file ``load_floorplan`` reads) to a PNG.

    Args:
        path_or_floorplan: a ``Floorplan`` or a path (.geojson/.json, .ifc, .yaml).
        out_png: output image path; written atomically.
        storey: IFC storey (name or elevation) when a path to an IFC file is given.
        title: figure title; default the floor plan's name and counts.

    Returns:
        The path of the written image.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if isinstance(path_or_floorplan, Floorplan):
        fp = path_or_floorplan
    else:
        from mfcl_jax.floorplan.load import load_floorplan

        fp = load_floorplan(path_or_floorplan, storey=storey)
    x0, y0, x1, y1 = fp.bounds
    aspect = (y1 - y0) / max(x1 - x0, 1e-6)
    w = 11.0
    fig, ax = plt.subplots(figsize=(w, min(max(w * aspect, 4.0), 16.0) + 0.6))
    draw_floorplan(ax, fp)
    area = float(np.sum(fp.room_areas))
    ax.set_title(
        title
        or f"{fp.name}: {len(fp.rooms)} rooms ({area:.0f} m²), "
        f"{len(fp.wall_polygons) + len(fp.walls)} walls, {len(fp.doors)} doors"
    )
    buf = io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=150, bbox_inches="tight")
    finally:
        plt.close(fig)
    # Checked, atomic, and with the umask's permissions (mfcl_jax.io.atomic).
    return atomic_write(out_png, buf.getvalue())
