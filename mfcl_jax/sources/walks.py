"""Walks through a floor plan: waypoint files, checks, door-to-door routes, random tours.

A walk is a waypoint polyline in B that the simulator smooths and samples
(``sim.sample_path``). ``route`` threads a given room sequence through the doors' midpoints;
``random_tours`` draws room sequences by a seeded random walk on the room graph, for
benchmark runs through buildings nobody hand-picked routes for.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, Point

from mfcl_jax.io.errors import DataError

__all__ = ["read_waypoints", "check_waypoints", "route", "random_tours", "path_length"]


def read_waypoints(path) -> np.ndarray:
    """Reads ``x,y`` per line (a header line is optional; blank and ``#`` lines skipped).

    Raises:
        DataError: naming the line and field of the first bad value.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise DataError(f"{path}: cannot read ({e})") from None
    pts, header_seen = [], False
    for no, row in enumerate(csv.reader(text.splitlines()), 1):
        cells = [c.strip() for c in row]
        if not cells or not any(cells) or cells[0].startswith("#"):
            continue
        if not pts and not header_seen and [c.lower() for c in cells] == ["x", "y"]:
            header_seen = True
            continue
        if len(cells) != 2:
            raise DataError(f"{path}: line {no}: expected 2 fields x,y, got {len(cells)}")
        vals = []
        for name, c in zip("xy", cells, strict=True):
            try:
                v = float(c)
            except ValueError:
                raise DataError(f"{path}: line {no}: field {name}: not a number {c!r}") from None
            if not math.isfinite(v):
                raise DataError(f"{path}: line {no}: field {name}: non-finite value {c!r}")
            vals.append(v)
        if pts and np.hypot(vals[0] - pts[-1][0], vals[1] - pts[-1][1]) < 1e-9:
            raise DataError(f"{path}: line {no}: waypoint repeats the previous one")
        pts.append(vals)
    if len(pts) < 2:
        raise DataError(f"{path}: need at least 2 waypoints, got {len(pts)}")
    return np.asarray(pts, np.float64)


def check_waypoints(fp, wp, where: str = "<waypoints>") -> None:
    """Raises ``DataError`` when a waypoint lies outside the building (its footprint), in a
    wall, or a leg crosses one."""
    inside = shapely.contains_xy(fp.footprint, wp[:, 0], wp[:, 1])
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        ox, oy = (float(v) for v in fp.offset)  # the message speaks the file's frame
        x0, y0, x1, y1 = np.asarray(fp.bounds) + (ox, oy, ox, oy)
        raise DataError(
            f"{where}: waypoint {i + 1} ({wp[i][0] + ox:.2f}, {wp[i][1] + oy:.2f}) lies outside "
            f"the building {fp.name} (its footprint spans x {x0:.2f}..{x1:.2f}, y {y0:.2f}.."
            f"{y1:.2f}; {int((~inside).sum())} of {len(wp)} waypoints outside); the LiDAR "
            "would see the outer walls from outside"
        )
    solid = fp.wall_solid
    for i in range(len(wp) - 1):
        leg = LineString(wp[i : i + 2])
        if leg.intersects(solid):
            hit = leg.intersection(solid)
            p = np.asarray(hit.representative_point().coords[0])
            raise DataError(
                f"{where}: waypoint {i + 1} -> {i + 2} ({wp[i][0]:.2f}, {wp[i][1]:.2f}) -> "
                f"({wp[i + 1][0]:.2f}, {wp[i + 1][1]:.2f}) passes through a wall of "
                f"{fp.name} near ({p[0]:.2f}, {p[1]:.2f})"
            )


def route(fp, rooms, through: float = 0.8, extra: dict | None = None) -> np.ndarray:
    """Waypoints visiting ``rooms`` in order: a room's interior point, then for every
    transition the two points ``through`` m either side of the shared door's midpoint.

    ``extra`` maps a position in the list (index of the room) to via points appended after
    that room's interior point.
    """
    extra = extra or {}
    by_name = {r.name: r for r in fp.rooms}

    def inside(name):
        p = by_name[name].polygon
        c = p.centroid
        return np.asarray((c if p.contains(c) else p.representative_point()).coords[0])

    pts = [inside(rooms[0])] + [np.asarray(v, float) for v in extra.get(0, [])]
    for i, (a, b) in enumerate(zip(rooms[:-1], rooms[1:], strict=True), 1):
        door = next((d for d in fp.doors if set(d.rooms) == {a, b}), None)
        if door is None:
            raise ValueError(f"{fp.name}: no door between {a!r} and {b!r}")
        m = door.segment.mean(0)
        u = door.segment[1] - door.segment[0]
        n = np.array([-u[1], u[0]]) / max(np.hypot(*u), 1e-9)
        poly_b = by_name[b].polygon
        ahead = poly_b.distance(Point(m + through * n)) < poly_b.distance(Point(m - through * n))
        s = 1.0 if ahead else -1.0
        pts += [m - s * through * n, m + s * through * n]
        if i < len(rooms) - 1 or extra.get(i):
            pts.append(inside(b))
        pts += [np.asarray(v, float) for v in extra.get(i, [])]
    if len(rooms) > 1 and not extra.get(len(rooms) - 1):
        pts.append(inside(rooms[-1]))
    out = [pts[0]]
    for p in pts[1:]:
        if np.hypot(*(p - out[-1])) > 0.05:
            out.append(p)
    return np.asarray(out)


def path_length(wp) -> float:
    """Length (m) of a waypoint polyline."""
    wp = np.asarray(wp, np.float64)
    return float(np.sum(np.hypot(*np.diff(wp, axis=0).T)))


def random_tours(
    fp,
    n: int,
    seed: int,
    min_len: float = 30.0,
    max_len: float = 70.0,
    min_area: float = 3.0,
    tries: int = 200,
) -> list[np.ndarray]:
    """Up to ``n`` walks along random room sequences (seeded), each ``min_len``-``max_len`` m.

    A tour starts in a random room of at least ``min_area`` m2 and moves to a random
    neighbour through a door (not straight back unless it must) until it is long enough;
    tours that cross a wall (``check_waypoints``) are redrawn. Fewer than ``n`` come back
    when the building does not allow them (e.g. one room).
    """
    rng = np.random.default_rng(seed)
    names = [r.name for r in fp.rooms if r.polygon.area >= min_area]
    nbrs: dict[str, list[str]] = {r.name: [] for r in fp.rooms}
    for d in fp.doors:
        if len(d.rooms) == 2 and all(r in nbrs for r in d.rooms):
            a, b = d.rooms
            nbrs[a].append(b)
            nbrs[b].append(a)
    out: list[np.ndarray] = []
    for _ in range(tries):
        if len(out) >= n or not names:
            break
        seq = [names[rng.integers(len(names))]]
        wp = None
        while len(seq) < 40:
            opts = [r for r in nbrs[seq[-1]] if len(seq) < 2 or r != seq[-2]] or nbrs[seq[-1]]
            if not opts:
                break
            seq.append(opts[rng.integers(len(opts))])
            try:
                cand = route(fp, seq)
            except ValueError:
                break
            if path_length(cand) > max_len:
                break
            wp = cand
            if path_length(wp) >= min_len:
                break
        if wp is None or path_length(wp) < min_len:
            continue
        try:
            check_waypoints(fp, wp)
        except DataError:
            continue
        out.append(wp)
    return out
