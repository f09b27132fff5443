"""Near-symmetric buildings whose one symmetry-breaking feature is not built as drawn.

A building with an exact self-motion ``g`` (the ``rotational`` family's exact seeds: a half
turn; ``bays``: one bay pitch) is given ONE feature that breaks the symmetry in its plan, a
1.2 m wall stub from a side of a room the first walk spends most of its path in (kept clear
of the first two walks, the scene's only walks from then on). The plan always has the stub;
the building as built (``Scene.as_built``) is one of:

* ``stub_built``: as drawn (the reference: the plan is right, and a walk that sees the stub
  can tell the building's halves apart);
* ``stub_unbuilt``: the stub is not there (reality is symmetric; where the robot stands by the
  stub, its scans fit the stub-free twin place better than the true one);
* ``stub_twin``: the plan has the stub at the image under ``g`` of that place, and the
  building has it there and a copy where the walk goes (reality is symmetric again, the other
  way round: the walk sees a stub the plan puts only in the other half);
* ``stub_moved``: the stub stands 0.4 m along its wall from where the plan has it.

In the last three the scans are evidence against the plan exactly where the plan is the only
thing that breaks the symmetry: a layer that weighs a contradiction there as a competitor that
lost commits to the wrong half of the building.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.sim.families.asbuilt import NotApplicable, seeded
from mfcl_jax.sim.families.walks import CLEAR, clearance

__all__ = ["NEAR_SYM_KINDS", "self_motion", "with_near_symmetry"]

NEAR_SYM_KINDS = ("stub_built", "stub_unbuilt", "stub_twin", "stub_moved")
STUB = 1.2  # m
STUB_T = 0.12  # m
MOVE = 0.4  # m, the moved stub's offset along its wall
WALKS = 2  # the walks simulated in these scenes (the stubs keep clear of them)


def self_motion(scene) -> np.ndarray | None:
    """An exact self-motion ``g = (x, y, theta)`` of the scene's plan, or None: a half turn
    about the footprint's centroid that maps the free space onto itself (area of the symmetric
    difference under 0.1 %), else the offset between the first two congruent bays ``B1``,
    ``B2`` (the ``bays`` family)."""
    fp = scene.floorplan
    free = shapely.union_all([r.polygon for r in fp.rooms])
    c = fp.footprint.centroid
    turned = affinity.rotate(free, 180, origin=c)
    if free.symmetric_difference(turned).area < 1e-3 * free.area:
        return np.array([2 * c.x, 2 * c.y, np.pi])
    names = set(fp.room_names)
    if {"B1", "B2"} <= names:
        a, b = fp.room("B1").polygon, fp.room("B2").polygon
        if abs(a.area - b.area) < 1e-6 * a.area:
            d = np.asarray(b.centroid.coords[0]) - np.asarray(a.centroid.coords[0])
            return np.array([d[0], d[1], 0.0])
    return None


def _apply(g, pts) -> np.ndarray:
    c, s = np.cos(g[2]), np.sin(g[2])
    p = np.asarray(pts, float)
    return p @ np.array([[c, s], [-s, c]]) + g[:2]


def _time_in_rooms(fp: Floorplan, walk) -> list[str]:
    """Rooms by the length of the walk's polyline inside them, longest first."""
    line = LineString(walk)
    lengths = {r.name: line.intersection(r.polygon).length for r in fp.rooms}
    return [k for k, v in sorted(lengths.items(), key=lambda kv: -kv[1]) if v > 0]


def _stub_in(fp: Floorplan, room: str, walks, g, rng) -> np.ndarray | None:
    """A stub from one of ``room``'s sides (at its middle, else at 0.3 or 0.7 of it) into
    it, clear of the doors, it, its image under ``g`` and its moved copy in free space and
    clear of every walk; None where none fits."""
    poly = fp.room(room).polygon
    free = shapely.union_all([r.polygon for r in fp.rooms])
    doors = shapely.union_all([LineString(d.segment).buffer(0.6) for d in fp.doors])
    x0, y0, x1, y1 = poly.bounds
    mids = []
    for f in (0.5, 0.3, 0.7):
        mx, my = x0 + f * (x1 - x0), y0 + f * (y1 - y0)
        mids += [(mx, y0, 0, 1), (mx, y1, 0, -1), (x0, my, 1, 0), (x1, my, -1, 0)]
    for i in rng.permutation(len(mids)):
        mx, my, dx, dy = mids[i]
        seg = np.array([[mx, my], [mx + dx * STUB, my + dy * STUB]])
        moved = seg + MOVE * np.array([dy, dx])  # along the wall the stub stands on
        segs = (seg, _apply(g, seg), moved)
        lines = [LineString(s) for s in segs]
        if not (
            poly.distance(shapely.Point(seg[0])) < 0.05
            and poly.covers(lines[0].centroid)
            and all(free.covers(ln.centroid) and not doors.intersects(ln) for ln in lines)
        ):
            continue
        if all(min(clearance(w, s[None]) for w in walks) >= CLEAR + STUB_T for s in segs):
            return seg
    return None


def _plus(fp: Floorplan, segs, name: str | None = None) -> Floorplan:
    """``fp`` with wall stubs ``segs`` added."""
    segs = np.asarray(segs, float).reshape(-1, 2, 2)
    return Floorplan(
        walls=np.concatenate([fp.walls, segs]),
        thickness=np.concatenate([fp.thickness, np.full(len(segs), STUB_T)]),
        rooms=fp.rooms, doors=fp.doors, wall_polygons=fp.wall_polygons,
        name=fp.name if name is None else name, source=fp.source,
    )  # fmt: skip


def with_near_symmetry(scene, kind: str, seed: int):
    """The scene's plan with one symmetry-breaking stub, built as ``kind`` says (module doc).

    Raises:
        ValueError: an unknown kind or a scene that already deviates.
        NotApplicable: the plan has no exact self-motion, or no room the first walk crosses
            takes a stub (and its image and moved copy) clear of the walks.
    """
    if kind not in NEAR_SYM_KINDS:
        raise ValueError(f"with_near_symmetry: unknown kind={kind!r}; kinds are {NEAR_SYM_KINDS}")
    if scene.as_built is not None:
        raise ValueError(f"with_near_symmetry: scene {scene.name!r} already deviates")
    g = self_motion(scene)
    if g is None:
        raise NotApplicable(f"with_near_symmetry: {scene.name!r} has no exact self-motion")
    rng = seeded("with_near_symmetry", scene, seed)
    fp, walks = scene.floorplan, list(scene.trajectories.values())[:WALKS]
    for room in _time_in_rooms(fp, walks[0]):
        seg = _stub_in(fp, room, walks, g, rng)
        if seg is not None:
            break
    else:
        raise NotApplicable(f"with_near_symmetry: no room of {scene.name!r} takes a stub")
    image = _apply(g, seg)
    plan = _plus(fp, [image if kind == "stub_twin" else seg], f"{fp.name}+stub")
    built = {
        "stub_built": None,
        "stub_unbuilt": fp.wall_faces,
        "stub_twin": _plus(fp, [seg, image]).wall_faces,
        "stub_moved": _plus(fp, [seg + MOVE * np.array([seg[1, 1] - seg[0, 1],
                                                        seg[1, 0] - seg[0, 0]]) / STUB]).wall_faces,
    }[kind]  # fmt: skip
    at = (image if kind == "stub_twin" else seg).round(2).tolist()
    return dataclasses.replace(
        scene,
        floorplan=plan,
        trajectories=dict(list(scene.trajectories.items())[:WALKS]),
        as_built=built,
        description=f"{scene.description}; plan: a stub {at} breaks its symmetry; as built: {kind}",
    )
