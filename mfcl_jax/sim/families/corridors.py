"""Corridor families: ``bays`` (congruent bays along a corridor) and ``corridor`` (a long
featureless corridor with few or no side openings).

Both run along x; the corridor's axis is at ``y = c / 2`` for a centre-line width ``c``.
"""

from __future__ import annotations

from mfcl_jax.sim.families.assemble import finish
from mfcl_jax.sim.families.common import JAMB, Plan, draw
from mfcl_jax.sim.families.rooms import random_point
from mfcl_jax.sim.families.walks import Walk

__all__ = ["bays", "corridor"]


def bays(rng, name: str):
    """3-6 congruent bays at one pitch north of a corridor, the door at the same offset in each.

    Every wall has one thickness, so the bay rooms are exact translated copies. The corridor
    may run past the bays at either end; the ends are either alike (same run-out, both
    sealed) or differ (another run-out, an end room, or an entrance).
    """
    t = draw(rng, 0.15, 0.25)
    n = int(rng.integers(3, 7))
    pitch = draw(rng, 4.5, min(8.0, 46.0 / n))
    depth, c = draw(rng, 4.5, 8.0), draw(rng, 2.0, 3.0)
    w = draw(rng, 0.9, 1.3)
    m = w / 2 + JAMB + t / 2
    offset = draw(rng, m, pitch - m)
    ends = str(rng.choice(["alike", "run-out", "end room", "entrance"]))
    e_w = draw(rng, 0.0, 4.0)
    e_e = e_w if ends == "alike" else draw(rng, 0.0, 4.0)
    if ends == "run-out":
        e_e = e_w + float(rng.choice([-1, 1])) * draw(rng, 1.5, 3.0)
        e_e = e_e if e_e >= 0 else e_w + 2.0
    x_b = e_w
    length = x_b + n * pitch + e_e
    plan = Plan(name, t)
    plan.box(0, 0, length, c)
    plan.box(x_b, c, x_b + n * pitch, c + depth)
    plan.room("C", (0, 0, length, c))
    bay_names = [f"B{k + 1}" for k in range(n)]
    for k, b in enumerate(bay_names):
        x0 = x_b + k * pitch
        plan.wall((x0, c), (x0, c + depth))
        plan.room(b, (x0, c, x0 + pitch, c + depth))
        plan.door((x0 + offset, c), (0, 1), w, ("C", b))
    rooms = ["C", *bay_names]
    note = f"ends {ends}"
    if ends == "end room":
        rw, rh = draw(rng, 4.0, 7.0), draw(rng, c + 1.5, c + depth)
        plan.box(length, 0, length + rw, rh)
        plan.room("E", (length, 0, length + rw, rh))
        plan.door((length, c / 2), (1, 0), min(w, c - 2 * JAMB - t), ("C", "E"))
        rooms.append("E")
    elif ends == "entrance":
        plan.door((length, c / 2), (1, 0), min(1.2, c - 2 * JAMB - t), ("C",))
    built = plan.build()
    axis = c / 2
    walks = {}
    # A: bay to bay, never past the first or last bay door (the periodic part).
    start = bay_names[int(rng.integers(1, n - 1))]
    wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng))
    target = draw(rng, 40, 70)
    walks["A"] = wk.wander(rng, ["C", *bay_names], target, visit=0.9, reach=8.0).waypoints(target)
    # B: from the west end of the corridor to its east end, then on through the building.
    wk = Walk(built, "C", (1.2, axis)).to((length - 1.2, axis))
    target = max(38.0, draw(rng, min(wk.length + 5, 75), 78))
    walks["B"] = wk.wander(rng, rooms, target, visit=0.6).waypoints(target)
    # C: from the last bay (or the end room) into the building.
    first = "E" if "E" in rooms else bay_names[-1]
    wk = Walk(built, first, random_point(built.fp.room(first).polygon, rng))
    target = draw(rng, 45, 78)
    walks["C"] = wk.wander(rng, rooms, target, visit=0.6).waypoints(target)
    desc = (
        f"bays: {n} congruent bays, pitch {pitch:.2f} m, depth {depth:.2f} m, corridor "
        f"{c:.2f} m; {note}"
    )
    return finish(built, walks, rng, desc)


def corridor(rng, name: str):
    """A 30-60 m corridor, 1.8-3 m clear, with 0-2 closets and maybe a room at one end."""
    t = draw(rng, 0.15, 0.3)
    c = draw(rng, 1.8, 3.0) + t
    end_room = rng.random() < 0.5
    rw = draw(rng, 4.0, 8.0) if end_room else 0.0
    length = draw(rng, 30.0, 60.0 - rw)
    plan = Plan(name, t)
    plan.box(0, 0, length, c)
    plan.room("C", (0, 0, length, c))
    rooms, notes = ["C"], []
    taken: list[tuple[float, float]] = []
    for k in range(int(rng.choice([0, 0, 1, 2]))):
        sw, sd = draw(rng, 2.5, 4.0), draw(rng, 2.5, 4.0)
        x0 = draw(rng, 3.0, length - 3.0 - sw)
        if any(x0 < b + 1.0 and a < x0 + sw + 1.0 for a, b in taken):
            continue
        taken.append((x0, x0 + sw))
        north = bool(rng.random() < 0.5)
        y0, y1, wy = (c, c + sd, c) if north else (-sd, 0.0, 0.0)
        plan.box(x0, y0, x0 + sw, y1)
        plan.room(f"S{k + 1}", (x0, y0, x0 + sw, y1))
        plan.door((x0 + sw / 2, wy), (0, 1), 0.9, ("C", f"S{k + 1}"))
        rooms.append(f"S{k + 1}")
        notes.append(f"closet at x={x0:.1f}")
    if end_room:
        rh = draw(rng, max(4.0, c + 1.0), 7.0)
        y0 = draw(rng, c - rh + 0.5, -0.5) if rh > c + 1.0 else (c - rh) / 2
        plan.box(length, y0, length + rw, y0 + rh)
        plan.room("E", (length, y0, length + rw, y0 + rh))
        plan.door((length, c / 2), (1, 0), min(1.2, c - 2 * JAMB - t), ("C", "E"))
        rooms.append("E")
        notes.append(f"end room {rw:.1f} x {rh:.1f} m")
    built = plan.build()
    axis = c / 2
    lane = min(0.3, (c - t) / 2 - 0.6)
    walks = {}
    # A: back and forth in the middle of the corridor, away from both ends.
    half = draw(rng, 6.0, min(12.0, length / 2 - 4.0))
    mid = length / 2 + draw(rng, -2.0, 2.0)
    a, b = mid - half, mid + half
    loop = [(a, axis + lane), (b, axis + lane), (b + 0.6, axis), (b, axis - lane)]
    loop += [(a, axis - lane), (a - 0.6, axis)]
    pts = [(a - 0.6, axis)] + loop * 4
    target = draw(rng, 38.0, 60.0)
    wk = Walk(built, "C", pts[0])
    for p in pts[1:]:
        wk.to(p)
    walks["A"] = wk.waypoints(target)
    # B: end to end (and into the end room), then back towards the middle.
    wk = Walk(built, "C", (1.2, axis)).to((length - 1.2, axis))
    if end_room:
        wk.door(built.doors_between("C", "E")[0]).visit(rng).visit(rng)
        wk.door(built.doors_between("C", "E")[0])
    wk.to((length / 3, axis))
    walks["B"] = wk.waypoints(78.0)
    # C: from a closet or the far end, the length of the corridor (and back on the other lane).
    first = rooms[1] if len(rooms) > 1 else "C"
    start = (
        random_point(built.fp.room(first).polygon, rng) if first != "C" else (length - 1.2, axis)
    )
    wk = Walk(built, first, start)
    if first != "C":
        wk.door(next(i for i, d in enumerate(built.doors) if first in d.rooms))
    ends = (1.2, length - 1.2) if wk.here[0] > length / 2 else (length - 1.2, 1.2)
    k = 0
    while wk.length < 38.0:
        far, back = ends[k % 2], ends[(k + 1) % 2]
        side = 1.0 if far > back else -1.0
        wk.to((far - side * 0.6, axis + side * lane)).to((far, axis))
        wk.to((far - side * 0.6, axis - side * lane)).to((back, axis - side * lane))
        k += 1
    walks["C"] = wk.waypoints(78.0)
    desc = f"corridor: {length:.1f} m x {c - t:.2f} m clear; " + (", ".join(notes) or "bare")
    return finish(built, walks, rng, desc)
