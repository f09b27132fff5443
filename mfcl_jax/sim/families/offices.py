"""The ``offices`` family: 8-20 near-identical small rooms along one or two corridors.

Three arrangements (x runs along the corridors):

* ``single``: one row of offices north of a corridor;
* ``double``: a row on each side of the corridor;
* ``twin``: two corridors and four rows (south, two back to back in the middle, north); a cross
  corridor at the east end joins the two.

Office widths are identical or differ by up to 3 % (each row still has one length); the door of
each office is either at the same offset in every office or at a random offset in each. A lobby
at the west end and an entrance at the east end appear on some seeds.
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.sim.families.assemble import finish
from mfcl_jax.sim.families.common import JAMB, Plan, draw
from mfcl_jax.sim.families.rooms import random_point
from mfcl_jax.sim.families.walks import Walk

__all__ = ["offices"]


def offices(rng, name: str):
    """An office floor; see the module doc."""
    kind = str(rng.choice(["single", "double", "twin"]))
    t = draw(rng, 0.15, 0.22)
    w0, depth = draw(rng, 3.0, 4.5), draw(rng, 3.5, 5.5)
    c = draw(rng, 2.2, 2.8) if kind == "twin" else draw(rng, 1.8, 2.8)
    per_row = {
        "single": (8, min(14, int(56 // w0))),
        "double": (4, min(10, int(56 // w0))),
        "twin": (2, 5),
    }[kind]
    m = int(rng.integers(per_row[0], per_row[1] + 1))
    jitter = float(rng.choice([0.0, 0.03]))
    same_doors = bool(rng.random() < 0.5)
    dw = draw(rng, 0.9, 1.1)
    length = m * w0
    # Rows as (y0, y1, corridor wall y, corridor name) and corridors as (name, y0, y1).
    if kind == "single":
        corridors = [("C1", 0.0, c)]
        rows = [(c, c + depth, c, "C1")]
    elif kind == "double":
        corridors = [("C1", depth, depth + c)]
        rows = [(0.0, depth, depth, "C1"), (depth + c, 2 * depth + c, depth + c, "C1")]
    else:
        y = [0.0, depth, depth + c, 2 * depth + c, 3 * depth + c, 3 * depth + 2 * c]
        corridors = [("C1", y[1], y[2]), ("C2", y[4], y[5])]
        rows = [
            (y[0], y[1], y[1], "C1"),
            (y[2], y[3], y[2], "C1"),
            (y[3], y[4], y[4], "C2"),
            (y[5], y[5] + depth, y[5], "C2"),
        ]
    plan = Plan(name, t)
    m_door = dw / 2 + JAMB + t / 2
    shared = draw(rng, m_door, 0.9 * w0 - m_door)
    offices_, k = [], 0
    for y0, y1, wy, cname in rows:
        widths = w0 * (1 + rng.uniform(-jitter, jitter, m))
        xs = np.concatenate([[0.0], np.cumsum(widths * length / widths.sum())])
        xs[-1] = length
        plan.box(0.0, y0, length, y1)
        for x0, x1 in zip(xs[:-1], xs[1:], strict=True):
            k += 1
            plan.wall((x0, y0), (x0, y1))
            plan.room(f"O{k}", (x0, y0, x1, y1))
            off = shared if same_doors else draw(rng, m_door, x1 - x0 - m_door)
            plan.door((x0 + off, wy), (0, 1), dw, (cname, f"O{k}"))
            offices_.append(f"O{k}")
    for cname, y0, y1 in corridors:
        plan.box(0.0, y0, length, y1)
        plan.room(cname, (0.0, y0, length, y1))
    hall = [cn for cn, *_ in corridors]
    notes = [f"{kind}, {len(offices_)} offices {w0:.2f} m x {depth:.2f} m"]
    notes.append("identical widths" if jitter == 0 else "widths within 3 %")
    notes.append("doors at one offset" if same_doors else "doors at random offsets")
    cw = min(dw, c - 2 * JAMB - t)  # a door in a corridor's end wall
    if kind == "twin":
        y0, y1 = corridors[0][1], corridors[1][2]
        plan.box(length, y0, length + c, y1)
        plan.room("X", (length, y0, length + c, y1))
        for cname, a, b in corridors:
            plan.door((length, (a + b) / 2), (1, 0), cw, (cname, "X"))
        hall.append("X")
    if rng.random() < 0.5:
        lw = draw(rng, 4.0, 7.0)
        y0, y1 = min(r[0] for r in rows), max(r[1] for r in rows)
        y0, y1 = min(y0, corridors[0][1]), max(y1, corridors[-1][2])
        plan.box(-lw, y0, 0.0, y1)
        plan.room("L", (-lw, y0, 0.0, y1))
        for cname, a, b in corridors:
            plan.door((0.0, (a + b) / 2), (1, 0), cw, (cname, "L"))
        notes.append(f"lobby {lw:.1f} m at the west end")
    elif kind != "twin" and rng.random() < 0.6:
        a, b = corridors[0][1:]
        plan.door((length, (a + b) / 2), (1, 0), cw, ("C1",))
        notes.append("entrance at the east end")
    built = plan.build()
    rooms = hall + offices_ + (["L"] if "L" in built.fp.room_names else [])
    walks = {}
    # A: along a corridor and in and out of offices, away from the lobby.
    first = corridors[0]
    axis = (first[1] + first[2]) / 2
    wk = Walk(built, "C1", (length * draw(rng, 0.3, 0.7), axis))
    target = draw(rng, 38, 60)
    walks["A"] = wk.wander(rng, hall + offices_, target, visit=0.7, reach=8.0).waypoints(target)
    # B: the whole corridor from the west end (or the lobby) and on.
    if "L" in rooms:
        wk = Walk(built, "L", random_point(built.fp.room("L").polygon, rng))
        wk.door(built.doors_between("C1", "L")[0])
    else:
        wk = Walk(built, "C1", (1.2, axis))
    wk.to((length - 1.2, axis))
    target = draw(rng, max(38.0, min(wk.length + 4.0, 70.0)), 78.0)
    walks["B"] = wk.wander(rng, rooms, target, visit=0.5).waypoints(target)
    # C: office hopping over the whole floor.
    start = str(rng.choice(offices_))
    wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng, 0.8))
    target = draw(rng, 50, 78)
    walks["C"] = wk.wander(rng, rooms, target, visit=0.8, inset=0.8, reach=6.0).waypoints(target)
    return finish(built, walks, rng, "offices: " + "; ".join(notes))
