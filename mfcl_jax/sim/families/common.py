"""Shared builders of the procedural families: seeded draws and an axis-aligned plan builder.

A family draws its dimensions, then describes the building to a ``Plan`` in wall centre lines:
full wall lines (``wall``, ``box``), room cells bounded by those lines (``room``), doors given by
their centre on a wall line and their clear width (``door``), openings without a door (``gap``)
and solid wall footprints (``solid``: columns, a solid core). ``Plan.build`` cuts the door
openings out of the wall lines, splits the lines at every junction (so that one wall segment is
one wall between two junctions, as ``with_as_built("missing_wall")`` needs), derives each room's
clear polygon (its cell minus the wall solid) and returns a validated ``Floorplan``.

Only axis-aligned walls are accepted: every family is built on a rectangular grid, and exact
90-degree rotations and mirror images of such a plan stay exact in floating point.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np
from shapely.geometry import LineString, MultiPolygon, Polygon, box
from shapely.ops import unary_union

from mfcl_jax.floorplan.model import Door, Floorplan, Room

__all__ = ["family_rng", "draw", "DoorSpec", "Plan", "Built", "JAMB"]

_EPS = 1e-9
# A door jamb must leave this much wall (m) between the opening and any junction.
JAMB = 0.35


def family_rng(family: str, seed: int) -> np.random.Generator:
    """The generator of one ``(family, seed)``: the seed mixed with a stable hash of the name."""
    return np.random.default_rng([zlib.crc32(family.encode()), int(seed)])


def draw(rng: np.random.Generator, lo: float, hi: float, step: float = 0.05) -> float:
    """A uniform draw in ``[lo, hi]`` rounded to ``step`` (plans are drawn to 5 cm)."""
    return float(np.clip(np.round(rng.uniform(lo, hi) / step) * step, lo, hi))


@dataclass(frozen=True)
class DoorSpec:
    """A door as the builder knows it (more than ``Door``: the walks need its geometry).

    Attributes:
        centre: ``(2,)`` opening centre on the wall centre line.
        normal: ``(2,)`` unit vector across the wall.
        width: clear opening width (m).
        thickness: thickness of the wall it opens.
        rooms: the one or two rooms it joins.
    """

    centre: np.ndarray
    normal: np.ndarray
    width: float
    thickness: float
    rooms: tuple[str, ...]

    @property
    def along(self) -> np.ndarray:
        """Unit vector along the wall."""
        return np.array([-self.normal[1], self.normal[0]])


@dataclass(frozen=True)
class Built:
    """A built plan: the floor plan and the builder's door records (same order as its doors)."""

    fp: Floorplan
    doors: tuple[DoorSpec, ...]

    def doors_between(self, a: str, b: str) -> list[int]:
        """Indices of the doors joining rooms ``a`` and ``b``."""
        return [i for i, d in enumerate(self.doors) if set(d.rooms) == {a, b}]


class Plan:
    """Collects walls, rooms and doors in wall centre-line coordinates (see the module doc)."""

    def __init__(self, name: str, thickness: float):
        self.name = name
        self.t = float(thickness)
        self._walls: list[tuple[np.ndarray, np.ndarray, float]] = []
        self._cuts: list[tuple[np.ndarray, np.ndarray]] = []
        self._cells: dict[str, Polygon] = {}
        self._doors: list[DoorSpec] = []
        self._solids: list[Polygon] = []

    @property
    def doors(self) -> tuple[DoorSpec, ...]:
        """The doors declared so far."""
        return tuple(self._doors)

    # ------------------------------------------------------------------ description
    def wall(self, p0, p1, t: float | None = None) -> None:
        """A straight wall centre line from ``p0`` to ``p1`` (horizontal or vertical)."""
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        if abs(p0[0] - p1[0]) > _EPS and abs(p0[1] - p1[1]) > _EPS:
            raise ValueError(f"{self.name}: wall {p0.tolist()}-{p1.tolist()} is not axis-aligned")
        if np.linalg.norm(p1 - p0) < 1e-6:
            raise ValueError(f"{self.name}: zero-length wall at {p0.tolist()}")
        self._walls.append((p0, p1, self.t if t is None else float(t)))

    def box(self, x0, y0, x1, y1, t: float | None = None) -> None:
        """The four walls of an axis-aligned rectangle."""
        c = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        for i in range(4):
            self.wall(c[i], c[(i + 1) % 4], t)

    def room(self, name: str, cell) -> None:
        """A room whose centre-line outline is ``cell`` (a Polygon or ``(x0, y0, x1, y1)``)."""
        if name in self._cells:
            raise ValueError(f"{self.name}: room {name!r} declared twice")
        self._cells[name] = cell if isinstance(cell, Polygon) else box(*cell)

    def door(self, centre, normal, width: float, rooms) -> int:
        """A door of clear ``width`` centred on a wall line; ``normal`` points across the wall."""
        centre, normal = np.asarray(centre, float), np.asarray(normal, float)
        normal = normal / np.linalg.norm(normal)
        t = self._thickness_at(centre, normal)
        spec = DoorSpec(centre, normal, float(width), t, tuple(rooms))
        half = spec.along * (width / 2 + t / 2)  # square wall caps reach t/2 into the gap
        self._cuts.append((centre - half, centre + half))
        self._doors.append(spec)
        return len(self._doors) - 1

    def gap(self, p, q) -> None:
        """Removes the wall centre line between ``p`` and ``q`` (an opening without a door)."""
        self._cuts.append((np.asarray(p, float), np.asarray(q, float)))

    def solid(self, poly: Polygon) -> None:
        """A wall footprint given directly (a column, a solid core)."""
        self._solids.append(poly)

    def _thickness_at(self, c: np.ndarray, normal: np.ndarray) -> float:
        ts = [t for p0, p1, t in self._walls if _on_segment(c, p0, p1) and _across(normal, p0, p1)]
        if not ts:
            raise ValueError(f"{self.name}: door at {c.tolist()} is on no wall line")
        return max(ts)

    # ------------------------------------------------------------------ build
    def build(self) -> Built:
        """Cuts openings, splits walls at junctions, derives rooms; returns a valid plan.

        Raises:
            ValueError: a door opening that a wall still blocks, or a room cell that the
                walls cut in pieces (generator bugs, never silently repaired).
        """
        segs, thick = self._wall_segments()
        parts = [
            LineString(s).buffer(t / 2, cap_style="square", join_style="mitre")
            for s, t in zip(segs, thick, strict=True)
        ]
        solid = unary_union(parts + self._solids)
        for i, d in enumerate(self._doors):
            hole = _door_box(d, shrink=1e-3)
            if hole.intersection(solid).area > 1e-9:
                raise ValueError(f"{self.name}: door #{i} at {d.centre.tolist()} is blocked")
        t_min = min([t for *_, t in self._walls], default=self.t)
        rooms = []
        for name, cell in self._cells.items():
            clear = cell.buffer(-t_min / 2, join_style="mitre").difference(solid)
            pieces = list(clear.geoms) if isinstance(clear, MultiPolygon) else [clear]
            pieces.sort(key=lambda p: -p.area)
            if not pieces or pieces[0].is_empty or sum(p.area for p in pieces[1:]) > 1e-6:
                raise ValueError(f"{self.name}: room {name!r} is not one clear region")
            rooms.append(Room(name, pieces[0].simplify(0.0)))
        doors = []
        for d in self._doors:
            reach = d.normal * (d.thickness / 2 + 0.25)
            doors.append(Door(np.stack([d.centre - reach, d.centre + reach]), d.rooms))
        fp = Floorplan(
            walls=np.asarray(segs, float).reshape(-1, 2, 2),
            thickness=np.asarray(thick, float),
            rooms=tuple(rooms),
            doors=tuple(doors),
            wall_polygons=tuple(self._solids),
            name=self.name,
            source=f"<family {self.name}>",
        )
        return Built(fp, tuple(self._doors))

    def _wall_segments(self):
        """Merged wall lines minus the cuts, split at every junction: ``(segments, thickness)``."""
        lines: dict[tuple, list[tuple[float, float]]] = {}
        for p0, p1, t in self._walls:
            ax = 0 if abs(p0[1] - p1[1]) < _EPS else 1  # 0: horizontal (runs in x)
            key = (ax, round(float(p0[1 - ax]), 9), t)
            lo, hi = sorted((float(p0[ax]), float(p1[ax])))
            lines.setdefault(key, []).append((lo, hi))
        ends = [(p0, p1) for p0, p1, _ in self._walls]
        segs, thick = [], []
        covered: dict[tuple, list] = {}  # (ax, off) -> intervals of thicker walls on that line
        for (ax, off, t), ivs in sorted(lines.items(), key=lambda kv: -kv[0][2]):
            merged = _union(ivs)
            below = covered.setdefault((ax, off), [])
            for lo, hi in merged:
                pieces = [(lo, hi)]
                for a, b in below:  # a thinner wall drawn inside a thicker one adds nothing
                    pieces = [r for p in pieces for r in _minus(p, a, b)]
                for c0, c1 in self._cuts:
                    if abs(c0[1 - ax] - off) < 1e-6 and abs(c1[1 - ax] - off) < 1e-6:
                        a, b = sorted((float(c0[ax]), float(c1[ax])))
                        pieces = [r for p in pieces for r in _minus(p, a, b)]
                cuts = _junctions(ax, off, ends)
                for a, b in pieces:
                    xs = [a] + [c for c in cuts if a + 1e-6 < c < b - 1e-6] + [b]
                    for u0, u1 in zip(xs[:-1], xs[1:], strict=True):
                        if u1 - u0 > 1e-6:
                            p, q = [0.0, 0.0], [0.0, 0.0]
                            p[ax], q[ax], p[1 - ax], q[1 - ax] = u0, u1, off, off
                            segs.append([p, q])
                            thick.append(t)
            below.extend(merged)
        return segs, thick


def _union(ivs):
    out = []
    for lo, hi in sorted(ivs):
        if out and lo <= out[-1][1] + 1e-9:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def _minus(iv, a, b):
    lo, hi = iv
    if b <= lo or a >= hi:
        return [iv]
    return [r for r in ((lo, a), (b, hi)) if r[1] - r[0] > 1e-9]


def _junctions(ax: int, off: float, ends) -> list[float]:
    """Positions along line ``ax``/``off`` where a perpendicular wall meets or crosses it."""
    out = set()
    for p0, p1 in ends:
        if abs(p0[ax] - p1[ax]) < _EPS:  # perpendicular to the line
            lo, hi = sorted((p0[1 - ax], p1[1 - ax]))
            if lo - 1e-6 <= off <= hi + 1e-6:
                out.add(round(float(p0[ax]), 9))
    return sorted(out)


def _on_segment(c, p0, p1) -> bool:
    d = p1 - p0
    s = float(np.dot(c - p0, d) / np.dot(d, d))
    return -1e-9 <= s <= 1 + 1e-9 and np.linalg.norm(p0 + s * d - c) < 1e-6


def _across(normal, p0, p1) -> bool:
    d = (p1 - p0) / np.linalg.norm(p1 - p0)
    return abs(float(np.dot(d, normal))) < 1e-6


def _door_box(d: DoorSpec, shrink: float = 0.0) -> Polygon:
    """The clear opening of a door: ``width`` along the wall by the wall thickness."""
    u, n = d.along * (d.width / 2 - shrink), d.normal * (d.thickness / 2 - shrink)
    c = d.centre
    return Polygon([c - u - n, c + u - n, c + u + n, c - u + n])
