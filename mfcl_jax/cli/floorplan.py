"""``mfcl floorplan ...``: look at a floor plan the way the system reads it."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["add_floorplan_commands", "cmd_floorplan_show", "add_rosmap_flags"]


def add_rosmap_flags(parser) -> None:
    """``--free-thresh`` and ``--occupied-thresh``: override a ROS map's YAML thresholds."""
    parser.add_argument(
        "--free-thresh",
        type=float,
        help="ROS map only: cells with occupancy p below this are free (overrides the YAML)",
    )
    parser.add_argument(
        "--occupied-thresh",
        type=float,
        help="ROS map only: cells with occupancy p above this are walls (overrides the YAML)",
    )


def add_floorplan_commands(subparsers) -> argparse.ArgumentParser:
    """Adds the ``floorplan`` command group (``show``) to an argparse sub-parser set."""
    fp = subparsers.add_parser("floorplan", help="inspect floor plans (IFC, GeoJSON, ROS map)")
    sub = fp.add_subparsers(dest="floorplan_command", required=True)
    show = sub.add_parser(
        "show", help="draw walls, rooms, doors and the room graph into a PNG, print a summary"
    )
    show.add_argument("model", type=Path, help="floor plan: .ifc, .geojson/.json or .yaml")
    show.add_argument(
        "--storey",
        help="IFC storey name or elevation (m); default the lowest storey with walls and spaces",
    )
    show.add_argument(
        "--cut-height",
        type=float,
        default=1.0,
        help="IFC cutting plane above the storey elevation (m), default 1.0",
    )
    add_rosmap_flags(show)
    show.add_argument("--out", type=Path, help="output PNG (default <model stem>.png here)")
    show.set_defaults(func=cmd_floorplan_show)
    return fp


def cmd_floorplan_show(args) -> int:
    import time

    import numpy as np

    from mfcl_jax.floorplan.load import floorplan_files, load_floorplan
    from mfcl_jax.io.atomic import check_output

    out = args.out or Path(f"{args.model.stem}.png")
    check_output(out, inputs=floorplan_files(args.model))
    from mfcl_jax.report.plots_floorplan import show_floorplan

    t0 = time.perf_counter()
    fp = load_floorplan(
        args.model,
        storey=args.storey,
        cut_height=args.cut_height,
        free_thresh=args.free_thresh,
        occupied_thresh=args.occupied_thresh,
    )
    dt = time.perf_counter() - t0
    show_floorplan(fp, out)
    n_edges = int((fp.adjacency.sum() - len(fp.rooms)) // 2)
    print(
        f"{fp.name}: {len(fp.rooms)} rooms, {float(np.sum(fp.room_areas)):.1f} m2 of rooms, "
        f"{len(fp.walls) + len(fp.wall_polygons)} walls, {len(fp.doors)} doors, "
        f"{n_edges} room-graph edges; loaded in {dt:.2f} s"
    )
    x0, y0, x1, y1 = fp.bounds
    print(f"extent {x1 - x0:.1f} x {y1 - y0:.1f} m; picture: {out}")
    if fp.storeys is not None:
        st = fp.storeys
        groups = ["+".join(st.names[s] for s in st.group(t)) for t in range(st.n_tiles)]
        print(f"{len(st.names)} storeys side by side, {st.n_tiles} places (congruent storeys "
              f"share one): {', '.join(groups)}")  # fmt: skip
    if np.any(fp.offset != 0):
        ox, oy = fp.offset
        print(f"local origin: plan coordinates = picture coordinates + ({ox:.3f}, {oy:.3f})")
    return 0
