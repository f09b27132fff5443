"""The ``ring`` family: a ring corridor (ONE room polygon with a hole) around a central core.

Outer rooms line all four sides of the building, the ring corridor runs inside them, and the
core inside the ring is either solid (a service core the LiDAR sees only from outside) or
2-4 rooms. Every outer and core room has a door onto the ring. Walks in the ring follow its
axis, a rectangle, round its corners.
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import box

from mfcl_jax.sim.families.assemble import finish
from mfcl_jax.sim.families.common import JAMB, Plan, draw
from mfcl_jax.sim.families.rooms import entrance, random_point, subdivide
from mfcl_jax.sim.families.walks import Walk

__all__ = ["ring"]


def _cuts(rng, lo: float, hi: float, first: float, last: float) -> list[float]:
    """Partitions from ``lo`` to ``hi``: rooms 3.5-7 m (the last up to 10.5 m), the first at
    least ``first`` and the last at least ``last`` long; both ends included."""
    xs, x = [lo], lo + max(first, draw(rng, 3.5, 7.0))
    while x <= hi - max(last, 3.5):
        xs.append(x)
        x += draw(rng, 3.5, 7.0)
    return xs + [hi]


def _loop_router(corners: np.ndarray):
    """Routes along the rectangle ``corners (4, 2)`` (the ring axis) the shorter way round."""
    lo, hi = corners.min(0), corners.max(0)
    perim = 2 * float(np.sum(hi - lo))

    def where(p):
        """Arc position of ``p`` projected on the nearest side of the rectangle."""
        d = [abs(p[1] - lo[1]), abs(p[0] - hi[0]), abs(p[1] - hi[1]), abs(p[0] - lo[0])]
        k = int(np.argmin(d))
        size = hi - lo
        along = [p[0] - lo[0], p[1] - lo[1], hi[0] - p[0], hi[1] - p[1]][k]
        return sum([size[0], size[1], size[0], size[1]][:k]) + float(np.clip(along, 0, size[k % 2]))

    arcs = np.array([0.0, hi[0] - lo[0], perim / 2, perim / 2 + hi[0] - lo[0]])
    ordered = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])

    def route(p, q):
        a, b = where(p), where(q)
        ahead = (b - a) % perim
        if ahead <= perim / 2:
            cs = [k for k in range(4) if 0 < (arcs[k] - a) % perim < ahead]
            cs.sort(key=lambda k: (arcs[k] - a) % perim)
        else:
            cs = [k for k in range(4) if 0 < (a - arcs[k]) % perim < perim - ahead]
            cs.sort(key=lambda k: (a - arcs[k]) % perim)
        return [ordered[k] for k in cs]

    return route


def ring(rng, name: str):
    """Outer rooms, a ring corridor and a solid or subdivided core; see the module doc."""
    w, h = draw(rng, 30.0, 50.0), draw(rng, 26.0, 40.0)
    t = draw(rng, 0.15, 0.25)
    d, c = draw(rng, 4.0, 6.5), draw(rng, 2.2, 3.2)
    dw = draw(rng, 0.9, 1.2)
    margin = dw / 2 + JAMB + t / 2
    o0, o1 = np.array([d, d]), np.array([w - d, h - d])  # ring, outer wall lines
    i0, i1 = o0 + c, o1 - c  # ring, inner wall lines
    plan = Plan(name, t)
    plan.box(0.0, 0.0, w, h, t + float(rng.choice([0.0, 0.1])))
    plan.box(*o0, *o1)
    plan.box(*i0, *i1)
    plan.room("K", box(*o0, *o1).difference(box(*i0, *i1)))
    cells: dict[str, tuple] = {}
    # South and north bands span the full width; east and west bands fit between them.
    corner = d + 2 * margin + 0.3
    for y0, y1, wy in ((0.0, d, d), (h - d, h, h - d)):
        xs = _cuts(rng, 0.0, w, corner, corner)
        for a, b in zip(xs[:-1], xs[1:], strict=True):
            cells[f"R{len(cells) + 1}"] = (a, y0, b, y1)
            lo, hi = max(a, d) + margin, min(b, w - d) - margin
            plan.door((draw(rng, lo, hi), wy), (0, 1), dw, ("K", f"R{len(cells)}"))
    for x0, x1, wx in ((0.0, d, d), (w - d, w, w - d)):
        ys = _cuts(rng, d, h - d, 3.5, 3.5)
        for a, b in zip(ys[:-1], ys[1:], strict=True):
            cells[f"R{len(cells) + 1}"] = (x0, a, x1, b)
            plan.door((wx, draw(rng, a + margin, b - margin)), (1, 0), dw, ("K", f"R{len(cells)}"))
    for r in cells.values():
        plan.box(*r)
    solid = bool(rng.random() < 0.35)
    if solid:
        plan.solid(box(*i0, *i1))
        core = "solid core"
    else:
        rects, cuts = subdivide(rng, (*i0, *i1), int(rng.integers(2, 5)), 3.5)
        rects, cuts = (rects, cuts) if rects is not None else ([(*i0, *i1)], [])
        for p, q in cuts:
            plan.wall(p, q)
        for r in rects:
            k = f"Q{sum(n.startswith('Q') for n in cells) + 1}"
            cells[k] = r
            _core_door(rng, plan, r, i0, i1, dw, margin, k)
        core = f"{len(rects)} core rooms"
    for k, r in cells.items():
        plan.room(k, r)
    if rng.random() < 0.5:
        entrance(rng, plan, {k: v for k, v in cells.items() if k.startswith("R")}, w, h)
    built = plan.build()
    axis = np.array(
        [o0 + c / 2, [o1[0] - c / 2, o0[1] + c / 2], o1 - c / 2, [o0[0] + c / 2, o1[1] - c / 2]]
    )
    routers = {"K": _loop_router(axis)}
    rooms = list(built.fp.room_names)
    walks = {}
    # A: round the ring corridor, never leaving it.
    k0, step = int(rng.integers(4)), int(rng.choice([1, -1]))
    wk = Walk(built, "K", axis[k0], routers)
    target = draw(rng, 40.0, 78.0)
    k = k0
    while wk.length < target:
        k = (k + step) % 4
        wk.to(axis[k])
    walks["A"] = wk.waypoints(target)
    # B: from an outer room across the ring into the core and on.
    start = str(rng.choice([r for r in rooms if r.startswith("R")]))
    wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng), routers)
    if not solid:
        q = str(rng.choice([r for r in rooms if r.startswith("Q")]))
        wk.door(built.doors_between(start, "K")[0]).door(built.doors_between("K", q)[0])
        wk.visit(rng)
    target = max(draw(rng, 40.0, 78.0), min(78.0, wk.length + 6.0))
    walks["B"] = wk.wander(rng, rooms, target, visit=0.7).waypoints(target)
    # C: room to room round the outside.
    start = str(rng.choice([r for r in rooms if r.startswith("R")]))
    wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng), routers)
    target = draw(rng, 50.0, 78.0)
    outer = ["K"] + [r for r in rooms if r.startswith("R")]
    walks["C"] = wk.wander(rng, outer, target, visit=0.6).waypoints(target)
    desc = f"ring: {w:.1f} m x {h:.1f} m, ring corridor {c - t:.2f} m clear, {core}"
    return finish(built, walks, rng, desc)


def _core_door(rng, plan: Plan, r, i0, i1, dw: float, margin: float, name: str) -> None:
    """A door from a core room onto the ring, in its longest side on the ring's inner wall."""
    x0, y0, x1, y1 = r
    sides = []
    if np.isclose(y0, i0[1]):
        sides.append((x1 - x0, lambda s: ((x0 + s, y0), (0, 1))))
    if np.isclose(y1, i1[1]):
        sides.append((x1 - x0, lambda s: ((x0 + s, y1), (0, 1))))
    if np.isclose(x0, i0[0]):
        sides.append((y1 - y0, lambda s: ((x0, y0 + s), (1, 0))))
    if np.isclose(x1, i1[0]):
        sides.append((y1 - y0, lambda s: ((x1, y0 + s), (1, 0))))
    run, at = max(sides, key=lambda s: s[0])
    centre, normal = at(draw(rng, margin, run - margin))
    plan.door(centre, normal, dw, ("K", name))
