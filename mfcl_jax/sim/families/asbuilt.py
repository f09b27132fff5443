"""As-built deviations: the real walls differ from the plan's in one way (``Scene.as_built``).

* ``missing_wall``: an interior wall segment of the plan is not there (in a plan without interior
  walls, a 1.5-3 m stretch of an outer wall);
* ``extra_partition``: a thin partition the plan lacks, standing out from a wall face, 0.5 m or
  more from every walk;
* ``moved_door``: a door opening is 0.6-1.5 m further along its wall than the plan has it; walks
  through that door step sideways in front of the wall and cross at the real opening.

Each returns a NEW ``Scene`` with the same plan and clutter (and the same walks but for the
detours of ``moved_door``).
"""

from __future__ import annotations

import dataclasses
import zlib

import numpy as np
import shapely
from shapely.geometry import LineString, MultiLineString, Polygon
from shapely.geometry.polygon import orient

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.sim.families.clutter import WALK_KEEP_OUT
from mfcl_jax.sim.families.walks import CLEAR, clearance
from mfcl_jax.sim.trajectory import sample_path

__all__ = ["with_as_built", "AS_BUILT_KINDS", "NotApplicable", "seeded"]


class NotApplicable(ValueError):
    """The building has nothing this deviation can change (no wall, door or room for it)."""


AS_BUILT_KINDS = ("missing_wall", "extra_partition", "moved_door")


def seeded(tag: str, scene, seed: int) -> np.random.Generator:
    """The generator of a fault: its name, the scene's name and the seed (checked)."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"{tag}: seed must be a non-negative integer, got seed={seed!r}")
    return np.random.default_rng([zlib.crc32(tag.encode()), zlib.crc32(scene.name.encode()), seed])


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
    rng = seeded(f"with_as_built/{kind}", scene, seed)
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
        raise NotApplicable(f"with_as_built: {scene.name!r} has no wall that can be missing")
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
    raise NotApplicable(f"with_as_built: no room for an extra partition in {scene.name!r}")


def _moved_door(scene, fp, rng):
    """Shifts one door opening 0.6-1.5 m along its wall; walks through it detour to it."""
    if not fp.doors:
        raise NotApplicable(f"with_as_built: {scene.name!r} has no door to move")
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
    raise NotApplicable(
        f"with_as_built: no door of {scene.name!r} can move without blocking a walk"
    )


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
