"""The ``mirror`` family: a wing and its mirror image about ``x = 0``, joined by a lobby.

The east wing is a rectangle cut into 3-5 rooms with doors on a random spanning tree; the west
wing is its exact mirror image (``x -> -x``). The lobby is centred on the axis and spans all or
part of the wings' height, so the building is mirror-symmetric and, since neither the wing nor
the lobby is symmetric about a horizontal line, not symmetric under a half turn.
"""

from __future__ import annotations

from mfcl_jax.sim.families.assemble import finish
from mfcl_jax.sim.families.common import JAMB, Plan, draw
from mfcl_jax.sim.families.rooms import connect, random_point, subdivide
from mfcl_jax.sim.families.views import View
from mfcl_jax.sim.families.walks import Walk

__all__ = ["mirror"]


def mirror(rng, name: str):
    """An east wing, its mirror image and a lobby on the axis; see the module doc."""
    t = draw(rng, 0.15, 0.25)
    while True:
        h, ww, lw = draw(rng, 12.0, 28.0), draw(rng, 10.0, 24.0), draw(rng, 3.0, 8.0)
        n = int(rng.integers(3, 6))
        rects, cuts = subdivide(rng, (lw / 2, 0.0, lw / 2 + ww, h), n, 3.2)
        if rects is None:
            continue
        full = bool(rng.random() < 0.5)
        ly0 = 0.0 if full else draw(rng, 0.0, h - 6.0)
        ly1 = h if full else draw(rng, ly0 + 5.0, min(h, ly0 + 12.0))
        if not full and abs(ly0 + ly1 - h) < 1.0:
            continue  # a lobby centred in height would make the plan symmetric under a half turn
        east = {f"E{k + 1}": r for k, r in enumerate(rects)}
        # One wing on a scratch plan, to draw its doors; then both wings on the real plan.
        scratch = Plan(name, t)
        for p, q in cuts:
            scratch.wall(p, q)
        for r in rects:
            scratch.box(*r)
        if not connect(rng, scratch, east, draw(rng, 0.9, 1.2)):
            continue
        dw = draw(rng, 0.9, 1.3)
        m = dw / 2 + JAMB + t / 2
        lobby_doors = []
        for k, (x0, y0, _, y1) in east.items():
            lo, hi = max(y0, ly0) + m, min(y1, ly1) - m
            if x0 == lw / 2 and hi - lo > 0.2:
                lobby_doors.append((k, draw(rng, lo, hi)))
        if lobby_doors:
            break
    plan = Plan(name, t)
    plan.box(-lw / 2, ly0, lw / 2, ly1)
    plan.room("L", (-lw / 2, ly0, lw / 2, ly1))
    keep = [lobby_doors[i] for i in sorted(rng.permutation(len(lobby_doors))[:2])]
    for side, v in (("E", View(plan)), ("W", View(plan, mirror=True))):
        for p, q in cuts:
            v.wall(p, q)
        for k, r in east.items():
            v.box(*r)
            v.room(side + k[1:], r)
        for d in scratch.doors:
            v.door(d.centre, d.normal, d.width, tuple(side + r[1:] for r in d.rooms))
        for k, y in keep:
            v.door((lw / 2, y), (1, 0), dw, ("L", side + k[1:]))
    if rng.random() < 0.6:
        plan.door((0.0, ly0), (0, 1), min(1.6, lw - 2 * JAMB - t), ("L",))
    built = plan.build()
    rooms = list(built.fp.room_names)
    wing = [r for r in rooms if r.startswith("E")]
    walks = {}
    # A: inside the east wing only (its mirror image is the west wing).
    start = str(rng.choice(wing))
    wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng))
    target = draw(rng, 38.0, 60.0)
    walks["A"] = wk.wander(rng, wing, target, visit=0.7).waypoints(target)
    # B: from the east wing across the lobby into the west wing.
    start = keep[0][0]
    wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng))
    wk.door(built.doors_between("L", start)[0]).visit(rng, 0.8)
    wk.door(built.doors_between("L", "W" + start[1:])[0])
    target = max(draw(rng, 40.0, 78.0), min(78.0, wk.length + 6.0))
    walks["B"] = wk.wander(rng, rooms, target, visit=0.6).waypoints(target)
    # C: from the lobby, anywhere.
    wk = Walk(built, "L", random_point(built.fp.room("L").polygon, rng, 0.8))
    target = draw(rng, 50.0, 78.0)
    walks["C"] = wk.wander(rng, rooms, target, visit=0.6).waypoints(target)
    lobby = "full-height lobby" if full else f"lobby y {ly0:.1f}-{ly1:.1f} m"
    desc = f"mirror: two {n}-room wings {ww:.1f} m x {h:.1f} m about x = 0, {lobby} {lw:.1f} m wide"
    return finish(built, walks, rng, desc)
