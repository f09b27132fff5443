"""Local origins for plans far from (0, 0): georeferenced plans keep their precision.

A plan in UTM (x ~ 5e5, y ~ 5e6 m) or any national grid, read into float32 rasters and
kernels, loses its centimetres (float32 has 24 bits: a step of 0.5 m at 5e6). Plans are
therefore read in float64 and, when their bounds reach farther than ``FAR`` (1 km) from the
origin, moved next to it before anything is rasterised:

    plan coordinates = local coordinates + offset

with ``offset`` the plan's centre rounded to a multiple of ``SNAP`` (1 km), recorded in
``Floorplan.offset``. Rounding keeps the shift a short number and makes the subtraction
exact for any coordinate within a factor of two of it. The local coordinates are then
rounded to ``DECIMALS`` (8) decimals, 10 nm: a file at 5e6 m holds its coordinates only to
about 1e-9 m, and a plan drawn in decimal metres (11.35) would otherwise come back as
11.350000000186 and shift a raster's size by one cell where its extent is an exact
multiple of the cell size. So a georeferenced plan gives the very rasters of the same plan
drawn near the origin. Everything downstream (rasters,
features, the localizer, anchors ``^B T_L``) works in the local frame; ``to_plan_frame``
maps poses and anchors back, in float64, where results leave the program (the CLI's
decision log, saved GeoJSON). Orientation is untouched: the shift is a pure translation.
"""

from __future__ import annotations

import numpy as np
import shapely

from mfcl_jax.floorplan.model import Door, Floorplan, Room

__all__ = [
    "FAR",
    "SNAP",
    "DECIMALS",
    "local_origin",
    "shift_plan",
    "to_plan_frame",
    "to_local_frame",
]

FAR = 1000.0
SNAP = 1000.0
DECIMALS = 8


def shift_plan(fp: Floorplan, shift, decimals: int | None = None) -> Floorplan:
    """The same plan with every coordinate reduced by ``shift (2,)`` and ``offset`` grown by
    it (so the plan-frame coordinates are unchanged), optionally rounded to ``decimals``."""
    shift = np.asarray(shift, np.float64).reshape(2)

    def move(q):
        q = np.asarray(q, np.float64) - shift
        return q if decimals is None else np.round(q, decimals)

    def geom(g):
        return shapely.transform(g, move)

    return Floorplan(
        walls=move(fp.walls),
        thickness=fp.thickness,
        rooms=tuple(Room(r.name, geom(r.polygon)) for r in fp.rooms),
        doors=tuple(Door(move(d.segment), d.rooms) for d in fp.doors),
        wall_polygons=tuple(geom(p) for p in fp.wall_polygons),
        name=fp.name,
        source=fp.source,
        offset=fp.offset + shift,
        walls_derived=fp.walls_derived,  # still the rooms' walls: rooms join across them
        outside_unknown=fp.outside_unknown,
    )


def local_origin(fp: Floorplan, far: float = FAR, snap: float = SNAP) -> Floorplan:
    """``fp`` itself when its bounds lie within ``far`` metres of the origin, otherwise the
    plan moved next to it (``shift_plan`` by its centre rounded to ``snap``, local
    coordinates rounded to ``DECIMALS``)."""
    x0, y0, x1, y1 = fp.bounds
    if max(abs(x0), abs(y0), abs(x1), abs(y1)) <= far:
        return fp
    centre = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    return shift_plan(fp, np.round(centre / snap) * snap, DECIMALS)


def to_plan_frame(pose_local, offset) -> np.ndarray:
    """Poses or anchors ``(*, 3)`` (or points ``(*, 2)``) in the local frame -> plan frame.

    Float64 throughout: ``x + offset_x`` keeps every bit a float64 anchor at 5e6 m can hold.
    """
    p = np.array(pose_local, dtype=np.float64)
    p[..., :2] += np.asarray(offset, np.float64).reshape(2)
    return p


def to_local_frame(pose_plan, offset) -> np.ndarray:
    """The inverse of ``to_plan_frame``: plan-frame poses or points -> local frame."""
    p = np.array(pose_plan, dtype=np.float64)
    p[..., :2] -= np.asarray(offset, np.float64).reshape(2)
    return p
