"""The two built-in stand-in buildings, one per regime of the paper (Section IV).

* ``three_rooms``: three adjacent, similar but non-congruent rooms "207", "208", "209" (the
  non-coherent, multimodal regime: a neighbouring room is a strong alias, but no exact period).
* ``symmetric_bays``: four congruent bays "R1".."R4" at an exact 7.30 m pitch, sealed at both
  ends (the coherent regime: a translational lattice of aliases broken only by the end walls).

All coordinates are metres in B; x runs along the row of rooms, y across it.
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import Polygon, box

from mfcl_jax.floorplan.model import Door, Floorplan, Room
from mfcl_jax.sim.scene import Scene, rect_segments

__all__ = ["three_rooms", "symmetric_bays", "BAY_PITCH"]


def _wall_with_doors(x: float, y0: float, y1: float, gaps: list[tuple[float, float]]):
    """A vertical wall centre line at ``x`` from ``y0`` to ``y1`` with door gaps in y."""
    segs, y = [], y0
    for g0, g1 in sorted(gaps):
        segs.append([[x, y], [x, g0]])
        y = g1
    segs.append([[x, y], [x, y1]])
    return segs


def _clutter(rects: list[tuple[float, float, float, float]], extra=()) -> np.ndarray:
    parts = [rect_segments(*r) for r in rects] + [
        np.asarray(e, float).reshape(-1, 2, 2) for e in extra
    ]
    return np.concatenate(parts, axis=0)


# Desk and table top height (m), for the 3-D LiDAR.
_DESK = 0.75

# ---------------------------------------------------------------------------- three rooms
# Partition centre lines (x) and building depth (y). Room lengths 13.8 / 14.6 / 14.2 m along x
# at the same 11.2 m depth: similar enough that a submap of one room also fits its neighbour
# (same width, doors at the same height in the shared walls), but not congruent.
_TR_X = (0.0, 13.8, 28.4, 42.6)
_TR_H = 11.2
_TR_EXT, _TR_INT = 0.30, 0.20
_TR_DOOR = (7.9, 9.3)  # door gap (y) in both partitions: 1.4 m wide, centre y = 8.6
_TR_SHAFT = (0.15, 9.45, 1.95, _TR_H - 0.15)  # service shaft in the NW corner of 207
_TR_PILASTER = (34.6, 0.15, 35.6, 0.85)  # column pilaster on the south wall of 209


def three_rooms() -> Scene:
    """Three adjacent non-congruent rooms 207, 208, 209 in a row (stand-in for the real site).

    Geometry (wall centre lines; exterior walls 0.30 m thick, partitions 0.20 m):

    * building 42.6 m x 11.2 m; partitions at x = 13.8 and x = 28.4;
    * room 207: x 0.15-13.7, y 0.15-11.05 minus a 1.8 m x 1.6 m service shaft in its NW corner
      (an L-shaped room: 6 corners, 144.8 m^2);
    * room 208: x 13.9-28.3, plain rectangle (4 corners, 157.0 m^2);
    * room 209: x 28.5-42.45 with a 1.0 m x 0.7 m column pilaster on its south wall (8 corners,
      151.4 m^2);
    * doors 207-208 and 208-209: 1.4 m gaps at y 7.9-9.3 in both partitions; exterior sealed.

    The shorter room dimension (10.9 m inside) is about twice a 5-7 m submap window. A window
    inside 209 shifted one room west (about -14.4 m, heading unchanged) lands on 208 with its
    long walls and its west wall + door in place: the one-room alias the paper reports.

    Clutter (LiDAR-visible, absent from the plan): desks, cabinets along walls and a meeting
    table in every room (heights for the 3-D LiDAR: desks and tables 0.75 m, cabinets 1.0-2.0 m,
    the bookcase row in 209 and both partitions up to the ceiling); as-built deviations: a
    3.4 m partition stub from the south wall of 209 at x = 38.6 (a later store-room partition)
    and a 2.5 m glazed partition in 207 at y = 4.6.

    Trajectories: "T1" 209 -> 208 -> 207 -> 208 -> 209 (start in 209, back to 209) and "T2"
    207 -> 208 -> 209 -> 208; both about 60 m.
    """
    x0, x1, x2, x3 = _TR_X
    h = _TR_H
    walls = [
        [[x0, 0.0], [x3, 0.0]],
        [[x3, 0.0], [x3, h]],
        [[x3, h], [x0, h]],
        [[x0, h], [x0, 0.0]],
    ]
    thick = [_TR_EXT] * 4
    for x in (x1, x2):
        part = _wall_with_doors(x, 0.0, h, [_TR_DOOR])
        walls += part
        thick += [_TR_INT] * len(part)
    e, i = _TR_EXT / 2, _TR_INT / 2
    shaft = box(*_TR_SHAFT)
    pilaster = box(*_TR_PILASTER)
    r207 = box(x0 + e, e, x1 - i, h - e).difference(shaft)
    r208 = box(x1 + i, e, x2 - i, h - e)
    r209 = box(x2 + i, e, x3 - e, h - e).difference(pilaster)
    rooms = (Room("207", _clean(r207)), Room("208", _clean(r208)), Room("209", _clean(r209)))
    dy = sum(_TR_DOOR) / 2
    doors = (
        Door(np.array([[x1 - 0.3, dy], [x1 + 0.3, dy]]), ("207", "208")),
        Door(np.array([[x2 - 0.3, dy], [x2 + 0.3, dy]]), ("208", "209")),
    )
    fp = Floorplan(
        walls=np.asarray(walls, float),
        thickness=np.asarray(thick, float),
        rooms=rooms,
        doors=doors,
        wall_polygons=(shaft, pilaster),
        name="three_rooms",
        source="<scene three_rooms>",
    )
    rects = [
        # 207: a row of desks along the south wall, cabinets on the north wall, a printer
        (2.6, 1.0, 4.2, 1.8, _DESK),
        (4.6, 1.0, 6.2, 1.8, _DESK),
        (8.4, 1.0, 10.0, 1.8, _DESK),
        (3.0, 10.5, 4.8, 11.05, 2.0),
        (5.4, 10.5, 6.3, 11.05, 1.2),
        (12.6, 2.8, 13.5, 3.5, 1.0),
        # 208: two desk islands, a meeting table, cabinets on both long walls
        (16.0, 2.0, 19.2, 3.6, _DESK),
        (22.0, 1.6, 25.2, 3.2, _DESK),
        (19.8, 9.4, 23.0, 10.4, _DESK),
        (15.0, 0.15, 16.8, 0.6, 1.2),
        (25.6, 10.6, 27.4, 11.05, 2.0),
        (26.8, 0.15, 28.2, 0.7, 1.6),
        # 209: desks in the south-west, a bookcase row, cabinets along the east wall
        (30.0, 1.2, 33.2, 2.0, _DESK),
        (31.0, 3.2, 34.2, 4.0, np.inf),
        (36.2, 10.5, 39.8, 11.05, 1.2),
        (41.9, 2.0, 42.45, 4.2, 1.8),
        (41.9, 8.6, 42.45, 10.0, 2.0),
    ]
    # As-built partitions (thin double-faced walls with an end cap).
    stub_209 = rect_segments(38.55, 0.15, 38.65, 3.55)
    glass_207 = rect_segments(9.6, 4.55, 12.1, 4.65)
    clutter = _clutter([r[:4] for r in rects], extra=(stub_209, glass_207))
    # Furniture heights (m; inf: up to the ceiling, as the partitions and the bookcase row).
    heights = np.repeat([r[4] for r in rects] + [np.inf, np.inf], 4)
    trajectories = {
        "T1": np.array(
            [
                [37.4, 6.4],
                [34.0, 7.2],
                [31.0, 8.6],
                [26.0, 8.6],
                [21.0, 6.2],
                [16.2, 8.6],
                [11.6, 8.6],
                [7.6, 6.8],
                [5.8, 5.4],
                [8.4, 4.2],
                [11.4, 6.4],
                [11.6, 8.6],
                [16.2, 8.6],
                [21.0, 5.4],
                [26.0, 8.6],
                [31.0, 8.6],
                [34.4, 6.8],
            ]
        ),
        "T2": np.array(
            [
                [3.6, 7.4],
                [7.8, 7.6],
                [11.6, 8.6],
                [16.2, 8.6],
                [21.0, 6.2],
                [26.0, 8.6],
                [31.0, 8.6],
                [35.0, 6.0],
                [40.6, 6.2],
                [40.6, 8.2],
                [35.6, 8.6],
                [31.0, 8.6],
                [26.0, 8.6],
                [21.5, 5.6],
                [18.0, 5.4],
            ]
        ),
    }
    return Scene(
        "three_rooms",
        fp,
        clutter,
        trajectories,
        description="three adjacent non-congruent rooms 207-209 (multimodal aliases)",
        clutter_height=heights,
    )


# ---------------------------------------------------------------------------- symmetric bays
BAY_PITCH = 7.30
_SB_N = 4
_SB_H = 6.4
_SB_T = 0.20  # every wall, exterior included, so that the bays are exactly congruent
_SB_DOOR = (1.2, 2.4)  # door gap (y) in every partition, centre y = 1.8


def symmetric_bays() -> Scene:
    """Four congruent bays R1..R4 in a row at a 7.30 m pitch, sealed at both ends.

    Geometry: all walls 0.20 m thick (centre lines); building 29.2 m x 6.4 m; partitions at
    x = 7.3 k (k = 1..3), each with a 1.2 m door gap at y 1.2-2.4; the end walls x = 0 and
    x = 29.2 are sealed and are the only structure that breaks the translation by one pitch.
    Each bay is a 7.1 m x 6.2 m rectangle (44.02 m^2). Clutter: a table, a shelf on the north
    wall and a cabinet on the south wall in every bay, at positions that differ per bay (not in
    the floor plan, so registration must rely on walls alone).

    Trajectories: "S1" from R1 (x = 1.0) along the door line to the far wall of R4; "S2" the
    same with the start moved 0.3 m (+x). Both about 29 m, so d_s = 6 m gives 12 windows.
    """
    h, t = _SB_H, _SB_T
    xs = [BAY_PITCH * k for k in range(_SB_N + 1)]
    walls = [
        [[xs[0], 0.0], [xs[-1], 0.0]],
        [[xs[-1], h], [xs[0], h]],
        [[xs[0], 0.0], [xs[0], h]],
        [[xs[-1], 0.0], [xs[-1], h]],
    ]
    for x in xs[1:-1]:
        walls += _wall_with_doors(x, 0.0, h, [_SB_DOOR])
    rooms = tuple(
        Room(f"R{k + 1}", box(xs[k] + t / 2, t / 2, xs[k + 1] - t / 2, h - t / 2))
        for k in range(_SB_N)
    )
    dy = sum(_SB_DOOR) / 2
    doors = tuple(
        Door(np.array([[x - 0.3, dy], [x + 0.3, dy]]), (f"R{k + 1}", f"R{k + 2}"))
        for k, x in enumerate(xs[1:-1])
    )
    fp = Floorplan(
        walls=np.asarray(walls, float),
        thickness=np.full(len(walls), t),
        rooms=rooms,
        doors=doors,
        name="symmetric_bays",
        source="<scene symmetric_bays>",
    )
    # Per-bay furniture offsets (x within the bay): table, north shelf, south cabinet.
    layout = [(3.6, 0.8, 4.6), (3.2, 2.4, 5.0), (4.0, 1.4, 3.8), (3.4, 3.0, 4.4)]
    rects = []
    for k, (tx, sx, cx) in enumerate(layout):
        o = xs[k]
        rects += [
            (o + tx, 3.7, o + tx + 1.8, 4.6),  # table (0.75 m)
            (o + sx, h - t / 2 - 0.45, o + sx + 1.6, h - t / 2),  # north shelf (2.0 m)
            (o + cx, t / 2, o + cx + 0.9, t / 2 + 0.5),  # south cabinet (1.2 m)
        ]
    start = np.array([1.0, 4.2])
    path = [[3.0, dy], [26.6, dy], [28.3, 3.2]]
    trajectories = {
        "S1": np.array([start, *path]),
        "S2": np.array([start + [0.3, 0.0], *path]),
    }
    return Scene(
        "symmetric_bays",
        fp,
        _clutter(rects),
        trajectories,
        description="four congruent bays, pitch 7.30 m, sealed ends (lattice aliases)",
        clutter_height=np.tile(np.repeat([_DESK, 2.0, 1.2], 4), _SB_N),
    )


def _clean(poly: Polygon) -> Polygon:
    """Drops collinear vertices so that corner counts are honest."""
    return poly.simplify(0.0)
