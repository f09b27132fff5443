"""Plan faults and as-built deviations: each returns a NEW ``Scene`` and changes only what it
says.

* ``with_clutter``: more furniture (the LiDAR's world), plan and walks untouched.
* ``with_as_built``: the real walls differ from the plan's (``Scene.as_built``): a wall that is
  missing, a partition the plan lacks, or a door opening shifted along its wall (walks through
  that door follow the real opening).
* ``with_scale_error``: the plan (what the robot is given) is scaled about its centre; the world
  (real walls, clutter) and the walks stay true to scale.

Apply ``with_as_built`` and ``with_clutter`` before ``with_scale_error``: both read the rooms
and doors of the plan as the true ones.
"""

from __future__ import annotations

import dataclasses
import math
import zlib

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString, MultiLineString, Polygon
from shapely.geometry.polygon import orient

from mfcl_jax.floorplan.families.clutter import WALK_KEEP_OUT, furnish
from mfcl_jax.floorplan.families.walks import CLEAR, clearance
from mfcl_jax.floorplan.model import Door, Floorplan, Room
from mfcl_jax.sim.trajectory import sample_path

__all__ = ["with_clutter", "with_as_built", "with_scale_error", "AS_BUILT_KINDS"]

AS_BUILT_KINDS = ("missing_wall", "extra_partition", "moved_door")


def _rng(tag: str, scene, seed: int) -> np.random.Generator:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"{tag}: seed must be a non-negative integer, got seed={seed!r}")
    return np.random.default_rng([zlib.crc32(tag.encode()), zlib.crc32(scene.name.encode()), seed])


def with_clutter(scene, area_fraction: float, seed: int):
    """Adds furniture covering about ``area_fraction`` of the floor, >= 0.5 m from every walk.

    Args:
        scene: a ``Scene``.
        area_fraction: target fraction of the rooms' floor area, in ``[0, 0.5]``.
        seed: non-negative integer.

    Returns:
        The scene with the new items appended to its clutter; its description ends with the
        fraction actually covered (less than asked where the walks leave too little room).
    """
    if not (isinstance(area_fraction, int | float) and 0.0 <= area_fraction <= 0.5):
        raise ValueError(f"with_clutter: area_fraction must be in [0, 0.5], got {area_fraction!r}")
    rng = _rng("with_clutter", scene, seed)
    items, got = furnish(
        scene.floorplan,
        scene.trajectories.values(),
        float(area_fraction),
        rng,
        world=scene.as_built,
        existing=scene.clutter,
    )
    return dataclasses.replace(
        scene,
        clutter=np.concatenate([scene.clutter, items]),
        description=(
            f"{scene.description}; clutter +{got:.3f} of the floor (asked {area_fraction:.3f})"
        ),
    )


def with_as_built(scene, kind: str, seed: int):
    """The same plan with reality deviating from it in one way (see the module doc).

    Args:
        scene: a ``Scene`` without as-built deviations yet.
        kind: ``"missing_wall"``, ``"extra_partition"`` or ``"moved_door"``.
        seed: non-negative integer (which wall, partition or door).

    Raises:
        ValueError: an unknown kind, a scene that already deviates, or no place where the
            deviation fits without blocking a walk.
    """
    if kind not in AS_BUILT_KINDS:
        raise ValueError(f"with_as_built: unknown kind={kind!r}; kinds are {AS_BUILT_KINDS}")
    if scene.as_built is not None:
        raise ValueError(
            f"with_as_built: scene {scene.name!r} already has as-built walls; apply one "
            "deviation to a scene as designed (and before with_scale_error)"
        )
    rng = _rng(f"with_as_built/{kind}", scene, seed)
    fp = scene.floorplan
    if kind == "missing_wall":
        return _missing_wall(scene, fp, rng)
    if kind == "extra_partition":
        return _extra_partition(scene, fp, rng)
    return _moved_door(scene, fp, rng)


def _faces(fp: Floorplan, walls=None, thickness=None, solid=None) -> np.ndarray:
    """Wall faces of ``fp`` with other wall centre lines, or of a given wall ``solid``."""
    if solid is not None:
        walls, thickness, polys = np.zeros((0, 2, 2)), np.zeros(0), shapely.get_parts(solid)
    else:
        polys = fp.wall_polygons
    return Floorplan(
        walls=walls,
        thickness=thickness,
        rooms=fp.rooms,
        doors=fp.doors,
        wall_polygons=tuple(polys),
        name=fp.name,
        source=fp.source,
    ).wall_faces


def _missing_wall(scene, fp, rng):
    """Removes one interior wall segment (between two junctions or a junction and a door);
    in a plan without interior walls, a 1.5-3 m stretch of an outer wall (a gap to outside)."""
    floor = shapely.union_all([r.polygon for r in fp.rooms])
    inner, outer = [], []
    for i, (seg, t) in enumerate(zip(fp.walls, fp.thickness, strict=True)):
        d = seg[1] - seg[0]
        n = np.array([-d[1], d[0]]) / np.linalg.norm(d) * (t / 2 + 0.15)
        mid = seg.mean(0)
        inside = floor.covers(shapely.points([mid + n, mid - n]))
        if inside.all() and np.linalg.norm(d) >= 0.5:
            inner.append(i)
        elif inside.any() and np.linalg.norm(d) >= 4.0:
            outer.append(i)
    walls, thick = list(fp.walls), list(fp.thickness)
    if inner:
        i = int(rng.choice(inner))
        a, b = fp.walls[i].round(2).tolist()
        what = f"wall {a}-{b} missing"
        del walls[i], thick[i]
    elif outer:
        i = int(rng.choice(outer))
        p, q = fp.walls[i]
        run = float(np.linalg.norm(q - p))
        gap = rng.uniform(1.5, 3.0)
        s0 = rng.uniform(1.0, run - 1.0 - gap)
        u = (q - p) / run
        walls[i] = np.stack([p, p + s0 * u])
        walls.append(np.stack([p + (s0 + gap) * u, q]))
        thick.append(thick[i])
        at = (p + (s0 + gap / 2) * u).round(2).tolist()
        what = f"a {gap:.1f} m stretch of the outer wall at {at} missing"
    else:
        raise ValueError(f"with_as_built: {scene.name!r} has no wall that can be missing")
    faces = _faces(fp, np.asarray(walls), np.asarray(thick))
    return _deviate(scene, faces, what)


def _extra_partition(scene, fp, rng):
    keep_out = _walk_zone(scene).union(MultiLineString(list(scene.clutter)).buffer(0.1))
    keep_out = keep_out.union(
        shapely.union_all([LineString(d.segment).buffer(0.6) for d in fp.doors])
    )
    areas = fp.room_areas / fp.room_areas.sum()
    for _ in range(500):
        room = fp.rooms[int(rng.choice(len(fp.rooms), p=areas))].polygon
        ring = np.asarray(orient(room, 1.0).exterior.coords)
        k = int(rng.integers(len(ring) - 1))
        p, q = ring[k], ring[k + 1]
        run = float(np.linalg.norm(q - p))
        if run < 1.5:
            continue
        u = (q - p) / run
        inward = np.array([-u[1], u[0]])
        at = p + u * rng.uniform(0.5, run - 0.5)
        length = rng.uniform(1.0, 3.0)
        half = u * 0.05
        base = at - inward * 0.02  # a little into the wall, so that the two fuse
        tip = at + inward * length
        part = Polygon([base - half, base + half, tip + half, tip - half])
        inner = Polygon([at - half, at + half, tip + half, tip - half])
        if room.covers(inner) and not keep_out.intersects(part):
            faces = _faces(fp, solid=fp.wall_solid.union(part))
            return _deviate(scene, faces, f"a {length:.1f} m partition at {at.round(2).tolist()}")
    raise ValueError(f"with_as_built: no room for an extra partition in {scene.name!r}")


def _moved_door(scene, fp, rng):
    """Shifts one door opening 0.6-1.5 m along its wall; walks through it detour to it."""
    if not fp.doors:
        raise ValueError(f"with_as_built: {scene.name!r} has no door to move")
    solid = fp.wall_solid
    shifts = np.round(np.arange(0.6, 1.51, 0.1), 2)
    for j in rng.permutation(len(fp.doors)):
        door = fp.doors[j]
        mid = np.asarray(door.segment, float).mean(0)
        n = np.diff(door.segment, axis=0)[0]
        n = n / np.linalg.norm(n)
        u = np.array([-n[1], n[0]])
        t = _thickness_at(fp, mid, u)
        gaps = LineString([mid - 30 * u, mid + 30 * u]).difference(solid)
        gap = next(
            (g for g in shapely.get_parts(gaps) if g.distance(shapely.Point(mid)) < 1e-6), None
        )
        if t is None or gap is None:
            continue
        a, b = np.asarray(gap.coords)[[0, -1]]
        width, centre = float(np.linalg.norm(b - a)), (a + b) / 2
        for shift in rng.permutation(np.concatenate([shifts, -shifts])):
            moved = _try_move(scene, fp, solid, centre, u, n, width, t, float(shift))
            if moved is not None:
                faces, walks = moved
                what = f"door {'/'.join(door.rooms)} opening moved {shift:+.2f} m along its wall"
                return _deviate(scene, faces, what, walks)
    raise ValueError(f"with_as_built: no door of {scene.name!r} can move without blocking a walk")


def _try_move(scene, fp, solid, centre, u, n, width, t, shift):
    """The real wall faces and walks with the opening at ``centre + shift u``, or None."""

    def rect(c, half_u, half_n):
        return Polygon(
            [
                c - half_u * u - half_n * n,
                c + half_u * u - half_n * n,
                c + half_u * u + half_n * n,
                c - half_u * u + half_n * n,
            ]
        )

    new_c = centre + shift * u
    new = rect(new_c, width / 2, t / 2)
    filled = solid.union(rect(centre, width / 2, t / 2))
    if new.difference(filled).area > 1e-6:
        return None  # the wall does not run that far
    near = rect(new_c, width / 2 + 0.15, t / 2 + 0.5).intersection(filled)
    if near.difference(rect(new_c, width / 2 + 0.15, t / 2 + 1e-6)).area > 1e-6:
        return None  # another wall meets this one there: no room for the jambs
    faces = _faces(fp, solid=filled.difference(new))
    world = np.concatenate([faces, scene.clutter])
    # Only walks that come near the old or the new opening can be affected.
    zone = rect(centre + shift / 2 * u, abs(shift) / 2 + width / 2 + 1.0, t / 2 + 1.0)
    walks = {}
    for name, wp in scene.trajectories.items():
        walks[name] = _detour(wp, centre, u, n, shift)
        if zone.distance(LineString(walks[name])) < 1e-9 and clearance(walks[name], world) < CLEAR:
            return None
    return faces, walks


def _detour(wp, centre, u, n, shift) -> np.ndarray:
    """A walk that crossed the door at ``centre`` crossing ``shift`` further along the wall.

    A crossing is two consecutive waypoints on the door's normal line on both sides of the
    wall; the walk now steps sideways in front of the wall, crosses, and steps back.
    """
    rel = wp - centre
    on = (np.abs(rel @ u) < 1e-6) & (np.abs(rel @ n) < 1.6)
    side = np.sign(rel @ n)
    out = [wp[0]]
    for i in range(1, len(wp)):
        if on[i - 1] and on[i] and side[i - 1] != side[i]:
            out += [wp[i - 1] + shift * u, wp[i] + shift * u]
        out.append(wp[i])
    return np.asarray(out)


def _thickness_at(fp, p, u):
    """Thickness of the wall whose centre line runs through ``p`` along ``u`` (None if none)."""
    for seg, t in zip(fp.walls, fp.thickness, strict=True):
        d = seg[1] - seg[0]
        if abs(d[0] * u[1] - d[1] * u[0]) < 1e-9 * np.linalg.norm(d):
            r = p - seg[0]
            if abs(d[0] * r[1] - d[1] * r[0]) / np.linalg.norm(d) < 1e-6:
                return float(t)
    return None


def _walk_zone(scene):
    parts = []
    for wp in scene.trajectories.values():
        parts.append(LineString(wp).buffer(WALK_KEEP_OUT, quad_segs=4))
        parts.append(LineString(sample_path(wp).poses[:, :2]).buffer(WALK_KEEP_OUT, quad_segs=4))
    return shapely.union_all(parts)


def _deviate(scene, faces, what, walks=None):
    return dataclasses.replace(
        scene,
        as_built=faces,
        trajectories=scene.trajectories if walks is None else walks,
        description=f"{scene.description}; as-built: {what}",
    )


def with_scale_error(scene, factor: float):
    """The plan scaled by ``factor`` about its centre; the world and the walks stay true.

    Args:
        scene: a ``Scene``.
        factor: scale of the plan (e.g. 1.01-1.02 for a 1-2 % drawing error), finite, > 0.

    Returns:
        The scene with the scaled plan and ``as_built`` set to the true wall faces, so that
        ``Scene.segments`` (what the LiDAR sees) is unchanged.
    """
    if not (isinstance(factor, int | float) and math.isfinite(factor) and factor > 0):
        raise ValueError(f"with_scale_error: factor must be a finite number > 0, got {factor!r}")
    fp = scene.floorplan
    x0, y0, x1, y1 = fp.bounds
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    f = float(factor)

    def geom(g):
        return affinity.scale(g, f, f, origin=(c[0], c[1]))

    plan = Floorplan(
        walls=c + f * (fp.walls - c),
        thickness=f * fp.thickness,
        rooms=tuple(Room(r.name, geom(r.polygon)) for r in fp.rooms),
        doors=tuple(Door(c + f * (np.asarray(d.segment) - c), d.rooms) for d in fp.doors),
        wall_polygons=tuple(geom(p) for p in fp.wall_polygons),
        name=fp.name,
        source=f"{fp.source} scaled x{f:g}",
    )
    return dataclasses.replace(
        scene,
        floorplan=plan,
        as_built=fp.wall_faces if scene.as_built is None else scene.as_built,
        description=f"{scene.description}; plan scale error x{f:g}",
    )
