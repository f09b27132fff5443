"""Room-based families: ``plain`` (a few rooms of random sizes) and ``offices`` (many
near-identical small rooms along corridors), and the subdivision both ``plain`` and ``mirror``
use: a rectangle cut recursively into rooms, joined by a random spanning tree of doors.
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import Point, box

from mfcl_jax.sim.families.assemble import finish
from mfcl_jax.sim.families.common import JAMB, Plan, draw
from mfcl_jax.sim.families.walks import Walk

__all__ = ["plain", "subdivide", "connect", "random_point", "entrance"]


def subdivide(rng, rect, n: int, min_side: float):
    """Cuts ``rect = (x0, y0, x1, y1)`` into ``n`` rectangles by recursive straight cuts.

    Returns:
        ``(cells, cuts)``: ``n`` rectangles and the cut lines ``((x, y), (x, y))``, or
        ``(None, None)`` when a cell could not be cut (too small).
    """
    cells, cuts = [tuple(rect)], []
    while len(cells) < n:
        cells.sort(key=lambda c: -(c[2] - c[0]) * (c[3] - c[1]))
        x0, y0, x1, y1 = cells[0]
        ax = 0 if x1 - x0 >= y1 - y0 else 1
        lo, hi = (x0, x1) if ax == 0 else (y0, y1)
        if hi - lo < 2 * min_side:
            return None, None
        c = draw(
            rng, max(lo + min_side, lo + 0.3 * (hi - lo)), min(hi - min_side, lo + 0.7 * (hi - lo))
        )
        cells.pop(0)
        if ax == 0:
            cells += [(x0, y0, c, y1), (c, y0, x1, y1)]
            cuts.append(((c, y0), (c, y1)))
        else:
            cells += [(x0, y0, x1, c), (x0, c, x1, y1)]
            cuts.append(((x0, c), (x1, c)))
    cells.sort(key=lambda c: (c[1], c[0]))
    return cells, cuts


def connect(rng, plan: Plan, cells: dict, width: float, extra: float = 0.25) -> bool:
    """Doors on shared walls of box cells: a random spanning tree plus a few extra doors.

    Args:
        cells: room name -> ``(x0, y0, x1, y1)`` centre-line box.
        width: clear door width.
        extra: probability of a door on a shared wall outside the tree.

    Returns:
        False when the cells cannot all be joined (shared walls too short).
    """
    names = list(cells)
    pairs = []
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            run = box(*cells[a]).boundary.intersection(box(*cells[b]).boundary)
            margin = width / 2 + JAMB + plan.t / 2
            if run.geom_type == "LineString" and run.length >= 2 * margin + 0.2:
                pairs.append((a, b, np.asarray(run.coords), margin))
    parent = {n: n for n in names}

    def root(n):
        while parent[n] != n:
            n = parent[n]
        return n

    for k in rng.permutation(len(pairs)):
        a, b, run, margin = pairs[k]
        joined = root(a) == root(b)
        if joined and rng.random() >= extra:
            continue
        parent[root(a)] = root(b)
        p0, p1 = run[0], run[-1]
        u = (p1 - p0) / np.linalg.norm(p1 - p0)
        s = draw(rng, margin, np.linalg.norm(p1 - p0) - margin)
        plan.door(p0 + s * u, (-u[1], u[0]), width, (a, b))
    return len({root(n) for n in names}) == 1


def random_point(poly, rng, inset: float = 1.0) -> np.ndarray:
    """A random point at least ``inset`` inside ``poly`` (0.5 m in rooms too small for that)."""
    region = poly.buffer(-inset)
    if region.is_empty:
        region = poly.buffer(-0.5)
    if region.is_empty:
        raise ValueError(f"no point 0.5 m inside a polygon of bounds {poly.bounds}")
    x0, y0, x1, y1 = region.bounds
    for _ in range(1000):
        p = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
        if region.contains(Point(p)):
            return p
    raise ValueError(f"no point {inset} m inside a polygon of bounds {poly.bounds}")


def plain(rng, name: str):
    """4-9 rooms of random sizes in one rectangle, doors at random; maybe an L-shaped room."""
    while True:
        w, h = draw(rng, 18, 34), draw(rng, 12, 24)
        t = draw(rng, 0.15, 0.25)
        n = int(rng.integers(4, 10))
        rects, cuts = subdivide(rng, (0, 0, w, h), n, 3.2)
        if rects is None:
            continue
        plan = Plan(name, t)
        plan.box(0, 0, w, h, t + float(rng.choice([0.0, 0.1])))
        for p, q in cuts:
            plan.wall(p, q)
        cells = {f"R{k + 1}": r for k, r in enumerate(rects)}
        for k, r in cells.items():
            plan.room(k, r)
        if not connect(rng, plan, cells, draw(rng, 0.9, 1.3)):
            continue
        if rng.random() < 0.5:
            entrance(rng, plan, cells, w, h)
        routers, notch = {}, ""
        if rng.random() < 0.6:  # a service shaft in a building corner makes its room an L
            routers, notch = _shaft(rng, plan, cells, w, h)
        built = plan.build()
        rooms = list(cells)
        walks = {}
        for label, lo, hi, visit in (("A", 40, 70, 0.5), ("B", 38, 58, 0.3), ("C", 50, 78, 0.8)):
            start = str(rng.choice(rooms))
            wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng), routers)
            target = draw(rng, lo, hi)
            walks[label] = wk.wander(rng, rooms, target, visit=visit).waypoints(target)
        desc = f"plain: {n} rooms of random sizes in {w:.1f} m x {h:.1f} m{notch}"
        return finish(built, walks, rng, desc)


def _shaft(rng, plan: Plan, cells: dict, w: float, h: float):
    """A solid service shaft in one building corner; returns the L-room's router and a note.

    The shaft is at most half the room less 0.9 m in each direction, so the room's centre
    sees every point of the L (the router sends walks through it). No shaft where it would
    come near a door.
    """
    corner = int(rng.integers(4))
    cx, cy = (0.0, w, w, 0.0)[corner], (0.0, 0.0, h, h)[corner]
    name = next(k for k, (x0, y0, x1, y1) in cells.items() if x0 <= cx <= x1 and y0 <= cy <= y1)
    x0, y0, x1, y1 = cells[name]
    a = draw(rng, 1.2, max(1.2, (x1 - x0) / 2 - 0.9))
    b = draw(rng, 1.2, max(1.2, (y1 - y0) / 2 - 0.9))
    xs = sorted((cx, cx + (a if cx == x0 else -a)))
    ys = sorted((cy, cy + (b if cy == y0 else -b)))
    shaft = box(xs[0], ys[0], xs[1], ys[1])
    if any(shaft.distance(Point(d.centre)) < d.width / 2 + 0.9 for d in plan.doors):
        return {}, ""
    plan.solid(shaft)
    hub = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    return {name: lambda p, q: [hub]}, f"; {name} is L-shaped (a {a:.2f} x {b:.2f} m shaft)"


def entrance(rng, plan: Plan, cells: dict, w: float, h: float) -> None:
    """An exterior door in the outer wall of a random room."""
    for name in rng.permutation(list(cells)):
        x0, y0, x1, y1 = cells[name]
        sides = [
            (y0 == 0, (x0, 0.0), (x1, 0.0), (0, -1)),
            (x1 == w, (w, y0), (w, y1), (1, 0)),
            (y1 == h, (x0, h), (x1, h), (0, 1)),
            (x0 == 0, (0.0, y0), (0.0, y1), (-1, 0)),
        ]
        for k in rng.permutation(4):
            outer, p0, p1, n = sides[k]
            p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
            run = float(np.linalg.norm(p1 - p0))
            if outer and run >= 4.0:
                s = draw(rng, 1.6, run - 1.6)
                plan.door(p0 + s * (p1 - p0) / run, n, 1.2, (str(name),))
                return
