"""The ``rotational`` family: a cross or a loop with 2-fold or 4-fold rotational symmetry.

One unit is described in a local frame and replayed through quarter-turn views about the
origin; with 2-fold symmetry the units at odd quarter turns are a second, different design, so
only the half turn maps the plan onto itself. Each unit has a handed feature (an off-centre wing,
a side room at one end of a leg), so the plan has no mirror symmetry.

* ``cross``: a central hall with four wings; a wing is a corridor room and an end room.
* ``loop``: a ring of four corridor legs around an open courtyard, with a room at each outer
  corner and a side room on the courtyard side of each leg.

On about half the seeds one alcove in unit 0 breaks the symmetry (the description says so).
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import box

from mfcl_jax.sim.families.assemble import finish
from mfcl_jax.sim.families.common import JAMB, Plan, draw
from mfcl_jax.sim.families.rooms import random_point
from mfcl_jax.sim.families.views import View
from mfcl_jax.sim.families.walks import Walk

__all__ = ["rotational"]


def _alcove(rng, v: View, x_lo: float, x_hi: float, y_wall: float, out: float):
    """A recess in the wall ``y = y_wall`` between ``x_lo`` and ``x_hi``, ``out`` = +-1."""
    aw, ad = draw(rng, 1.3, 2.0), draw(rng, 0.7, 1.2)
    x0 = draw(rng, x_lo + 0.6, x_hi - aw - 0.6)
    y1 = y_wall + out * ad
    v.gap((x0, y_wall), (x0 + aw, y_wall))
    v.wall((x0, y_wall), (x0, y1))
    v.wall((x0, y1), (x0 + aw, y1))
    v.wall((x0 + aw, y1), (x0 + aw, y_wall))
    return (x0, min(y_wall, y1), x0 + aw, max(y_wall, y1)), f"{aw:.1f} x {ad:.1f} m alcove"


def _cross(rng, plan: Plan, fold: int, broken: bool):
    """Hall ``H``, wings ``W1..W4`` and end rooms ``E1..E4``; returns the note on the alcove."""
    t = plan.t
    half = [draw(rng, 4.0, 6.5)]
    half.append(half[0] if fold == 4 else draw(rng, 3.5, 6.5))
    plan.box(-half[0], -half[1], half[0], half[1])
    plan.room("H", (-half[0], -half[1], half[0], half[1]))
    dw = draw(rng, 0.9, 1.2)
    m = dw / 2 + JAMB + t / 2
    designs = []
    for _ in range(1 if fold == 4 else 2):
        designs.append(
            {"u": rng.uniform(size=6), "l": draw(rng, 4.0, 9.0), "e": draw(rng, 3.5, 6.0)}
        )
    note = ""
    for k in range(4):
        h, s = half[k % 2], half[(k + 1) % 2]
        d = designs[k % len(designs)]
        u = d["u"]
        # The wing band |y| <= s - 0.6; the wing is off-centre in it (the unit's handedness).
        b = np.round(3.0 + u[0] * (min(6.0, 2 * s - 1.2) - 3.0), 2)
        y0 = np.round(-s + 0.6 + u[1] * (2 * s - 1.2 - b), 2)
        b2 = np.round(b + u[2] * (min(2 * s - 1.2, b + 4.0) - b), 2)
        y1 = np.round(
            max(-s + 0.6, y0 + b - b2)
            + u[3] * (min(y0, s - 0.6 - b2) - max(-s + 0.6, y0 + b - b2)),
            2,
        )
        x1, x2 = h + d["l"], h + d["l"] + d["e"]
        v = View(plan, rot=k)
        v.box(h, y0, x1, y0 + b)
        v.box(x1, y1, x2, y1 + b2)
        wing = box(h, y0, x1, y0 + b)
        if broken and k == 0:
            recess, note = _alcove(rng, v, h, x1, y0 + b, 1.0)
            wing = wing.union(box(*recess))
        v.room(f"W{k + 1}", wing)
        v.room(f"E{k + 1}", (x1, y1, x2, y1 + b2))
        v.door((h, y0 + m + u[4] * (b - 2 * m)), (1, 0), dw, ("H", f"W{k + 1}"))
        v.door((x1, y0 + m + u[5] * (b - 2 * m)), (1, 0), dw, (f"W{k + 1}", f"E{k + 1}"))
    return note, [[f"W{k + 1}", f"E{k + 1}"] for k in range(4)]


def _loop(rng, plan: Plan, fold: int, broken: bool):
    """Legs ``C1..C4``, corner rooms ``E1..E4``, side rooms ``S1..S4`` round a courtyard."""
    t = plan.t
    q, c = draw(rng, 5.5, 7.5), draw(rng, 2.2, 3.0)
    half = [q + draw(rng, 3.0, 10.0)]
    half.append(half[0] if fold == 4 else q + draw(rng, 3.0, 10.0))
    cw = min(draw(rng, 0.9, 1.2), c - 2 * JAMB - t - 0.05)
    designs = [
        (draw(rng, 2.5, 4.0), draw(rng, 2.0, q - c - 0.5)) for _ in range(1 if fold == 4 else 2)
    ]
    note = ""
    for k in range(4):
        xh, yh = half[k % 2], half[(k + 1) % 2]
        sr, sd = designs[k % len(designs)]
        v = View(plan, rot=k)
        leg = box(-xh + q, -yh, xh - q, -yh + c)
        v.box(*leg.bounds)
        v.box(xh - q, -yh, xh, -yh + q)
        v.box(xh - q - sr, -yh + c, xh - q, -yh + c + sd)
        if broken and k == 0:
            recess, note = _alcove(rng, v, -xh + q, xh - q, -yh, -1.0)
            leg = leg.union(box(*recess))
        v.room(f"C{k + 1}", leg)
        v.room(f"E{k + 1}", (xh - q, -yh, xh, -yh + q))
        v.room(f"S{k + 1}", (xh - q - sr, -yh + c, xh - q, -yh + c + sd))
        prev = f"E{(k - 1) % 4 + 1}"
        v.door((xh - q, -yh + c / 2), (1, 0), cw, (f"C{k + 1}", f"E{k + 1}"))
        v.door((-xh + q, -yh + c / 2), (1, 0), cw, (f"C{k + 1}", prev))
        v.door((xh - q - sr / 2, -yh + c), (0, 1), 0.9, (f"C{k + 1}", f"S{k + 1}"))
    return note, [[f"C{k + 1}", f"E{k + 1}", f"S{k + 1}"] for k in range(4)]


def rotational(rng, name: str):
    """A cross or a loop, 2-fold or 4-fold, with or without one alcove; see the module doc."""
    layout = str(rng.choice(["cross", "loop"]))
    fold = int(rng.choice([2, 4]))
    broken = bool(rng.random() < 0.5)
    plan = Plan(name, draw(rng, 0.15, 0.25))
    note, units = (_cross if layout == "cross" else _loop)(rng, plan, fold, broken)
    built = plan.build()
    rooms = list(built.fp.room_names)
    walks = {}
    # A: inside one unit that the alcove (if any) does not mark.
    unit = units[int(rng.integers(1, 4))]
    wk = Walk(built, unit[1], random_point(built.fp.room(unit[1]).polygon, rng))
    target = draw(rng, 38.0, 55.0)
    walks["A"] = wk.wander(rng, unit, target, visit=0.8).waypoints(target)
    # B: across the building from unit 2 or 3, through unit 0 or 1 (the alcove's unit, if any).
    first = units[int(rng.integers(2, 4))][1]
    wk = Walk(built, first, random_point(built.fp.room(first).polygon, rng))
    goal = units[int(rng.integers(0, 2))]
    for _ in range(60):
        if wk.room in goal:
            break
        wk.wander(rng, rooms, wk.length + 1e-3, visit=0.2)
    target = max(draw(rng, 45.0, 78.0), min(78.0, wk.length + 8.0))
    walks["B"] = wk.wander(rng, rooms, target, visit=0.5).waypoints(target)
    # C: a long stroll anywhere.
    start = str(rng.choice(rooms))
    wk = Walk(built, start, random_point(built.fp.room(start).polygon, rng))
    target = draw(rng, 50.0, 78.0)
    walks["C"] = wk.wander(rng, rooms, target, visit=0.6).waypoints(target)
    sym = f"{fold}-fold rotational symmetry, " + (
        f"broken by a {note} in unit 1" if broken else "exact"
    )
    return finish(built, walks, rng, f"rotational: {layout}; {sym}")
