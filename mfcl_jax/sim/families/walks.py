"""Walks through a built plan: waypoint polylines that pass doors near their middle.

A ``Walk`` is a cursor that knows which room it is in. ``to`` moves within the room (straight
when the room's clear interior allows it, else through a family-supplied router), ``door``
crosses a door on its normal line through the centre, from a point in front of it to a point
behind it, and ``wander`` strolls through a set of rooms until a length is reached. ``clearance``
measures what the simulator will actually drive: the waypoint polyline and the smoothed path.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import shapely
from shapely.geometry import LineString, Point

from mfcl_jax.sim.families.common import Built
from mfcl_jax.sim.trajectory import sample_path

__all__ = ["CLEAR", "Walk", "clearance", "trim", "polyline_length", "dense"]

# What every walk keeps from every wall face and clutter item (m), in the plan and in reality.
CLEAR = 0.35
# Walks are designed with more room than that from the plan's walls, so that they survive
# as-built deviations and furniture placed at CLEAR + 0.15 from them.
_DESIGN = 0.45
# How far in front of a door a walk lines up (m, beyond the wall face, at most).
_APPROACH = 1.0
# How far from the walls a walk goes round a room: leaves a 0.7 m strip for desks and shelves
# (furniture keeps 0.5 m from walks).
_TOUR = 1.2

Router = Callable[[np.ndarray, np.ndarray], list]


def polyline_length(wp) -> float:
    wp = np.asarray(wp, float)
    return float(np.sum(np.linalg.norm(np.diff(wp, axis=0), axis=1)))


def dense(wp, step: float = 0.05) -> np.ndarray:
    """Points every ``step`` metres along a polyline ``(P, 2)`` (the corners included)."""
    wp = np.asarray(wp, float)
    out = [wp[:1]]
    for a, b in zip(wp[:-1], wp[1:], strict=True):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def trim(wp, length: float) -> np.ndarray:
    """The first ``length`` metres of a polyline."""
    wp = np.asarray(wp, float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(wp, axis=0), axis=1))])
    if s[-1] <= length:
        return wp
    k = int(np.searchsorted(s, length))
    f = (length - s[k - 1]) / (s[k] - s[k - 1])
    return np.concatenate([wp[:k], [wp[k - 1] + f * (wp[k] - wp[k - 1])]])


def clearance(wp, segments) -> float:
    """Smallest distance (m) from the polyline and from its smoothed path to ``segments``.

    The polyline is sampled every 0.1 m, so a walk that starts in free space cannot cross a
    segment (or enter a solid behind one) without a sample within 0.05 m of it.

    Args:
        wp: ``(P, 2)`` waypoints.
        segments: ``(K, 2, 2)`` obstacle segments (wall faces, clutter).
    """
    segs = np.asarray(segments, float).reshape(-1, 2, 2)
    if len(segs) == 0:
        return float("inf")
    tree = shapely.STRtree(shapely.linestrings(segs))
    pts = shapely.points(np.concatenate([dense(wp, 0.1), sample_path(wp).poses[:, :2]]))
    _, dist = tree.query_nearest(pts, return_distance=True, all_matches=False)
    return float(np.min(dist))


class Walk:
    """A waypoint polyline under construction, with the room it currently is in.

    Args:
        built: the plan.
        room: the starting room.
        start: ``(2,)`` starting point inside ``room``.
        routers: room name -> ``f(p, q)`` giving the intermediate waypoints from ``p`` to
            ``q`` inside that room, for rooms that are not convex (rings, column halls).
    """

    def __init__(self, built: Built, room: str, start, routers: dict[str, Router] | None = None):
        self.built = built
        self.room = room
        self.pts = [np.asarray(start, float)]
        self.routers = routers or {}
        self._came_from: str | None = None
        self._clear = {r.name: r.polygon.buffer(-_DESIGN) for r in built.fp.rooms}

    @property
    def here(self) -> np.ndarray:
        return self.pts[-1]

    @property
    def length(self) -> float:
        return polyline_length(self.pts) if len(self.pts) > 1 else 0.0

    def to(self, p) -> Walk:
        """Moves to ``p`` inside the current room."""
        p = np.asarray(p, float)
        if np.linalg.norm(p - self.here) < 1e-6:
            return self
        if self._visible(self.here, p):
            self.pts.append(p)
        elif self.room in self.routers:
            self.pts.extend(np.asarray(q, float) for q in self.routers[self.room](self.here, p))
            self.pts.append(p)
        else:
            raise ValueError(
                f"{self.built.fp.name}: no straight way from {self.here.round(2).tolist()} to "
                f"{p.round(2).tolist()} in room {self.room!r}"
            )
        return self

    def _visible(self, p, q) -> bool:
        return self._clear[self.room].covers(LineString([p, q]))

    def door(self, i: int) -> Walk:
        """Crosses door ``i`` from the current room into the other one (or out of the building)."""
        d = self.built.doors[i]
        if self.room not in d.rooms:
            raise ValueError(f"{self.built.fp.name}: door #{i} does not open from {self.room!r}")
        sign = self._side(d, self.room)
        other = next((r for r in d.rooms if r != self.room), None)
        if other is None:
            raise ValueError(f"{self.built.fp.name}: walks stay inside; door #{i} leads out")
        near = d.centre + sign * d.normal * self._approach(d, sign, self.room)
        far = d.centre - sign * d.normal * self._approach(d, -sign, other)
        self.to(near)
        self.pts.append(far)
        self._came_from, self.room = self.room, other
        return self

    def _side(self, d, room) -> float:
        probe = d.centre + d.normal * (d.thickness / 2 + 0.05)
        poly = self.built.fp.room(room).polygon
        return 1.0 if poly.distance(Point(probe)) < 0.02 else -1.0

    def _approach(self, d, sign, room) -> float:
        """Distance from the wall centre line to the line-up point on one side of a door."""
        poly = self.built.fp.room(room).polygon
        ray = LineString([d.centre, d.centre + sign * d.normal * 60.0])
        inside = ray.intersection(poly)
        depth = (
            inside.length
            if inside.geom_type == "LineString"
            else min(g.length for g in inside.geoms if g.distance(Point(d.centre)) < d.thickness)
        )
        return d.thickness / 2 + min(_APPROACH, depth / 2)

    def visit(self, rng: np.random.Generator, inset: float = 1.0) -> Walk:
        """Moves to a random point of the current room at least ``inset`` from its walls."""
        region = self.built.fp.room(self.room).polygon.buffer(-inset)
        if region.is_empty:
            return self
        x0, y0, x1, y1 = region.bounds
        for _ in range(200):
            p = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
            if region.contains(Point(p)) and (
                self._visible(self.here, p) or self.room in self.routers
            ):
                return self.to(p)
        return self

    def tour(self, rng: np.random.Generator, inset: float = _TOUR) -> Walk:
        """Goes once round the current room ``inset`` from its walls (a visit if too small)."""
        ring = self.built.fp.room(self.room).polygon.buffer(-inset, join_style="mitre")
        if ring.is_empty or ring.geom_type != "Polygon" or ring.area < 1.0:
            return self.visit(rng, min(inset, 0.8))
        xy = np.asarray(ring.exterior.coords)[:-1]
        k = int(np.argmin(np.linalg.norm(xy - self.here, axis=1)))
        for p in np.roll(xy, -k, axis=0):
            self.to(p)
        return self.to(xy[k])

    def wander(
        self,
        rng: np.random.Generator,
        rooms,
        length: float,
        visit: float = 0.5,
        inset=1.0,
        reach: float | None = None,
    ) -> Walk:
        """Strolls through doors among ``rooms`` until the walk is ``length`` long.

        In each room it may first visit a random point (probability ``visit``); in a dead end it
        goes round the room before turning back. It prefers not to go straight back to the
        room it came from and, given ``reach`` (m), doors nearer than about ``reach``.
        """
        rooms = set(rooms)
        for _ in range(400):
            if self.length >= length:
                break
            exits = [
                i
                for i, d in enumerate(self.built.doors)
                if self.room in d.rooms and len(d.rooms) == 2 and set(d.rooms) <= rooms
            ]
            if not exits:
                raise ValueError(f"{self.built.fp.name}: room {self.room!r} has no way on")
            onward = [i for i in exits if self._came_from not in self.built.doors[i].rooms]
            if not onward:  # a dead end: look round it before turning back
                self.tour(rng, max(inset, _TOUR))
            elif rng.random() < visit:
                self.visit(rng, inset)
            pick = np.asarray(onward or exits)
            if reach is None:
                self.door(int(rng.choice(pick)))
            else:
                far = np.array(
                    [np.linalg.norm(self.built.doors[i].centre - self.here) for i in pick]
                )
                w = np.exp(-far / reach)
                self.door(int(rng.choice(pick, p=w / w.sum())))
        return self

    def waypoints(self, max_length: float | None = None) -> np.ndarray:
        """The polyline, trimmed to ``max_length`` if given; consecutive repeats removed."""
        wp = np.asarray(self.pts, float)
        wp = wp if max_length is None else trim(wp, max_length)
        keep = np.concatenate([[True], np.linalg.norm(np.diff(wp, axis=0), axis=1) > 1e-6])
        return wp[keep]
