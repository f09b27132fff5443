"""The ``tower`` family: buildings of several storeys, the most common symmetry of all.

``make_tower(kind, seed, n)`` builds ``n`` storeys from the procedural families (an
``offices`` floor for the typical storey, a ``plain`` floor for a distinct ground floor):

* ``typical``: a distinct ground floor under ``n - 1`` identical office floors;
* ``one_room``: ``n`` office floors, identical but for one room: each floor above the first
  has a short wall stub in a room of its own;
* ``rotated``: a distinct ground floor under office floors that alternate with their
  half-turn (the same outline, the layout turned by 180 degrees about the floor's centre).

Every storey gets its family's walks (in the storey's own frame). The truth a walk should end
in: on a storey congruent to another (``Tower.congruent``), AMBIGUOUS(storey) or DEFER, never
COMMIT; elsewhere a commit must name the walk's storey.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.floorplan.storeys import congruence
from mfcl_jax.sim.families.walks import CLEAR, clearance
from mfcl_jax.sim.scenes import Scene

__all__ = ["TOWER_KINDS", "Tower", "make_tower"]

TOWER_KINDS = ("typical", "one_room", "rotated")
_STUB = 1.2  # m: the wall stub that sets a floor apart
_STUB_T = 0.12


@dataclass(frozen=True)
class Tower:
    """A building of storeys (lowest first) and the walks on each.

    Attributes:
        name: ``tower-<kind>-<seed>``.
        storeys: ``[(name, plan)]`` in each storey's own frame.
        scenes: one ``Scene`` per storey (its plan, clutter and walks).
        congruent: per storey, whether another storey is congruent to it (no scan can tell
            them apart).
        features: per storey, the segment ``(2, 2)`` that sets it apart from the typical
            floor (``one_room``: its stub), or None.
    """

    name: str
    storeys: list
    scenes: list
    congruent: list
    features: list


def _stub(fp: Floorplan, room: str, walks, rng) -> np.ndarray | None:
    """A wall stub ``(2, 2)`` from the middle of one of ``room``'s sides into the room, kept
    ``CLEAR`` + its half thickness from every walk; None where none fits."""
    poly = fp.room(room).polygon
    x0, y0, x1, y1 = poly.bounds
    mids = [((x0 + x1) / 2, y0, 0, 1), ((x0 + x1) / 2, y1, 0, -1),
            (x0, (y0 + y1) / 2, 1, 0), (x1, (y0 + y1) / 2, -1, 0)]  # fmt: skip
    for i in rng.permutation(len(mids)):
        mx, my, dx, dy = mids[i]
        seg = np.array([[mx, my], [mx + dx * _STUB, my + dy * _STUB]])
        if min((clearance(w, seg[None]) for w in walks), default=9.0) >= CLEAR + _STUB_T:
            return seg
    return None


def _with_stub(fp: Floorplan, seg, name: str) -> Floorplan:
    return Floorplan(
        walls=np.concatenate([fp.walls, seg[None]]),
        thickness=np.concatenate([fp.thickness, [_STUB_T]]),
        rooms=fp.rooms, doors=fp.doors, wall_polygons=fp.wall_polygons, name=name,
        source=fp.source,
    )  # fmt: skip


def _half_turn(scene: Scene) -> Scene:
    """The scene turned by 180 degrees about its footprint's centroid ``c``: p -> 2c - p."""
    c = np.asarray(scene.floorplan.footprint.centroid.coords[0])

    def tf(p):
        return 2 * c - np.asarray(p, float)

    fp = scene.floorplan.transformed((2 * c[0], 2 * c[1], math.pi))
    walks = {k: tf(w) for k, w in scene.trajectories.items()}
    return Scene(fp.name, fp, tf(scene.clutter), walks, clutter_height=scene.clutter_height)


def make_tower(kind: str, seed: int, n: int = 4) -> Tower:
    """Builds tower ``seed`` of ``kind`` with ``n`` storeys (see the module doc).

    Raises:
        ValueError: an unknown kind or fewer than 2 storeys.
    """
    from mfcl_jax.sim.families import make_scene

    if kind not in TOWER_KINDS:
        raise ValueError(f"unknown tower kind {kind!r}; known: {', '.join(TOWER_KINDS)}")
    if n < 2:
        raise ValueError(f"a tower needs at least 2 storeys, got n={n}")
    rng = np.random.default_rng([seed, TOWER_KINDS.index(kind), 54])
    typical = make_scene("offices", seed)
    ground = make_scene("plain", seed)
    scenes, features = [], []
    if kind == "one_room":
        rooms = [r.name for r in typical.floorplan.rooms if r.name.startswith("O")]
        walks = list(typical.trajectories.values())
        scenes, features = [typical], [None]
        for r in rng.permutation(rooms):
            if len(scenes) == n:
                break
            seg = _stub(typical.floorplan, str(r), walks, rng)
            if seg is None:
                continue
            fp = _with_stub(typical.floorplan, seg, f"{typical.name}+{r}")
            scenes.append(
                Scene(
                    fp.name,
                    fp,
                    typical.clutter,
                    typical.trajectories,
                    clutter_height=typical.clutter_height,
                )
            )
            features.append(seg)
        if len(scenes) < 2:
            raise ValueError(f"tower-one_room-{seed}: no room takes a stub clear of the walks")
    else:
        scenes, features = [ground], [None]
        for i in range(1, n):
            turned = kind == "rotated" and i % 2 == 0
            scenes.append(_half_turn(typical) if turned else typical)
            features.append(None)
    names = ["G" if kind != "one_room" else "L0"] + [f"L{i}" for i in range(1, len(scenes))]
    storeys = [(nm, s.floorplan) for nm, s in zip(names, scenes, strict=True)]
    congruent = [
        any(j != i and congruence(a, b) is not None for j, (_, b) in enumerate(storeys))
        for i, (_, a) in enumerate(storeys)
    ]
    return Tower(f"tower-{kind}-{seed}", storeys, scenes, congruent, features)
