"""The ``hall`` family: an open hall on a regular column grid, maybe with a few side rooms.

Columns are square wall footprints on a grid centred in the hall, at least 3/4 of a pitch from
the walls. Walks in the hall follow the aisles (the lines half a pitch from the column lines),
which keep at least ``pitch / 2 - size / 2`` (>= 1.6 m) from every column; side-room doors sit
on an aisle so that walks reach them straight.
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import box

from mfcl_jax.sim.families.assemble import finish
from mfcl_jax.sim.families.common import JAMB, Plan, draw
from mfcl_jax.sim.families.walks import Walk

__all__ = ["hall"]


def _grid(extent: float, pitch: float) -> np.ndarray:
    """Column lines centred in ``[0, extent]``, at least ``0.75 pitch`` from both ends."""
    n = int(np.floor((extent - 1.5 * pitch) / pitch)) + 1
    return (extent - (n - 1) * pitch) / 2 + pitch * np.arange(n)


def _aisle_router(ax: np.ndarray, ay: np.ndarray):
    """Routes between two points on aisles along the aisle grid (an L through aisle nodes)."""

    def snap(p):
        on_x, on_y = np.isclose(ax, p[0]), np.isclose(ay, p[1])
        if on_x.any():
            return np.array([p[0], ay[np.argmin(abs(ay - p[1]))]])
        if on_y.any():
            return np.array([ax[np.argmin(abs(ax - p[0]))], p[1]])
        raise ValueError(f"hall walk point {np.round(p, 2).tolist()} is on no aisle")

    def route(p, q):
        a, b = snap(p), snap(q)
        return [a, np.array([b[0], a[1]]), b]

    return route


def hall(rng, name: str):
    """A 20-40 m hall with 0.4-0.8 m columns at a 4-8 m pitch and 0-3 side rooms."""
    w, h = draw(rng, 20.0, 40.0), draw(rng, 20.0, 37.0)
    t = draw(rng, 0.2, 0.3)
    size, pitch = draw(rng, 0.4, 0.8), draw(rng, 4.0, 8.0)
    cx, cy = _grid(w, pitch), _grid(h, pitch)
    ax = np.concatenate([cx - pitch / 2, [cx[-1] + pitch / 2]])
    ay = np.concatenate([cy - pitch / 2, [cy[-1] + pitch / 2]])
    plan = Plan(name, t)
    plan.box(0.0, 0.0, w, h)
    cells = {"H": box(0.0, 0.0, w, h)}
    for x in cx:
        for y in cy:
            plan.solid(box(x - size / 2, y - size / 2, x + size / 2, y + size / 2))
    dw = draw(rng, 0.9, 1.3)
    margin = dw / 2 + JAMB + t / 2
    side: list[str] = []
    # Side rooms south (doors on vertical aisles) and east (doors on horizontal aisles).
    for wall, lines, extent in (("south", ax, w), ("east", ay, h)):
        taken: list[tuple[float, float]] = []
        for i in rng.permutation(len(lines))[: int(rng.choice([0, 1, 1, 2]))]:
            a = lines[i]
            rw, rd = draw(rng, 4.0, 8.0), draw(rng, 4.0, 6.0)
            lo = a - draw(rng, margin, rw - margin)
            if lo < 0 or lo + rw > extent or any(lo < b and a0 < lo + rw for a0, b in taken):
                continue
            taken.append((lo, lo + rw))
            k = f"S{len(side) + 1}"
            rect = (lo, -rd, lo + rw, 0.0) if wall == "south" else (w, lo, w + rd, lo + rw)
            plan.box(*rect)
            cells[k] = box(*rect)
            centre, normal = ((a, 0.0), (0, 1)) if wall == "south" else ((w, a), (1, 0))
            plan.door(centre, normal, dw, ("H", k))
            side.append(k)
    if rng.random() < 0.5:  # an entrance on a vertical aisle in the north wall
        plan.door((float(rng.choice(ax[1:-1])), h), (0, 1), 1.6, ("H",))
    for k, cell in cells.items():
        plan.room(k, cell)
    built = plan.build()
    routers = {"H": _aisle_router(ax, ay)}
    walks = {}
    # A: loops on inner aisles, among the columns only (the lattice part).
    i0, i1 = sorted(rng.choice(np.arange(1, len(ax) - 1), 2, replace=len(ax) < 4))
    j0, j1 = sorted(rng.choice(np.arange(1, len(ay) - 1), 2, replace=len(ay) < 4))
    i1, j1 = max(i1, i0 + 1), max(j1, j0 + 1)
    loop = [(ax[i0], ay[j0]), (ax[i1], ay[j0]), (ax[i1], ay[j1]), (ax[i0], ay[j1])]
    wk = Walk(built, "H", loop[0], routers)
    target = draw(rng, 38.0, 65.0)
    while wk.length < target:
        for p in loop[1:] + loop[:1]:
            wk.to(p)
    walks["A"] = wk.waypoints(target)
    # B: into every side room, then round the outer aisles (along the walls).
    ring = [(ax[0], ay[0]), (ax[-1], ay[0]), (ax[-1], ay[-1]), (ax[0], ay[-1])]
    k0 = int(rng.integers(4))
    wk = Walk(built, "H", ring[k0], routers)
    target = draw(rng, 45.0, 78.0)
    for k in side:
        wk.door(built.doors_between("H", k)[0]).visit(rng, 1.2)
        wk.door(built.doors_between("H", k)[0])
    while wk.length < target:
        for p in ring[k0 + 1 :] + ring[: k0 + 1]:
            wk.to(p)
    walks["B"] = wk.waypoints(target)
    # C: a serpentine over every other vertical aisle.
    wk = Walk(built, "H", (ax[0], ay[0]), routers)
    target = draw(rng, 50.0, 78.0)
    snake = []
    for i, x in enumerate(ax[::2]):
        ys = (ay[0], ay[-1]) if i % 2 == 0 else (ay[-1], ay[0])
        snake += [(x, ys[0]), (x, ys[1])]
    while wk.length < target:
        for p in snake:
            wk.to(p)
        snake = snake[::-1]
    walks["C"] = wk.waypoints(target)
    desc = (
        f"hall: {w:.1f} m x {h:.1f} m, {len(cx)} x {len(cy)} columns {size:.2f} m at "
        f"{pitch:.2f} m; {len(side)} side rooms"
    )
    return finish(built, walks, rng, desc)
