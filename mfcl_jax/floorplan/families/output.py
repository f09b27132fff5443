"""Files of a family scene: its floor plan as GeoJSON and a picture of plan and walks."""

from __future__ import annotations

import os
import tempfile
import textwrap
from pathlib import Path

from mfcl_jax.floorplan.geojson import save_geojson

__all__ = ["write_family_geojson", "plot_family"]


def write_family_geojson(scene, path) -> Path:
    """Writes the scene's floor plan (walls, rooms, doors; not clutter or walks) as GeoJSON."""
    return Path(save_geojson(scene.floorplan, path))


def plot_family(scene, out_png) -> Path:
    """Draws the floor plan, the clutter, the real walls where they differ and every walk.

    Args:
        scene: a ``Scene``.
        out_png: output image path; written atomically.

    Returns:
        The path of the PNG written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from mfcl_jax.evaluate.plots_scene import draw_scene

    x0, y0, x1, y1 = scene.floorplan.bounds
    width = 11.0
    fig, ax = plt.subplots(figsize=(width, width * (y1 - y0 + 2.0) / (x1 - x0 + 2.0) + 2.4))
    draw_scene(ax, scene, title="\n".join(textwrap.wrap(f"{scene.name}: {scene.description}", 100)))
    ax.title.set_fontsize(10)
    if scene.as_built is not None:  # dashed over the plan's walls where they differ
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
    out = Path(out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.stem}.", suffix=".png")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
        os.replace(tmp, out)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out
