"""The floor-plan model: walls, named rooms, doors and the room graph they induce. Host-side
and immutable (NumPy + shapely); kernels see the ``Rasters`` built from it (``raster``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.ops import unary_union

from mfcl_jax.floorplan import passages
from mfcl_jax.floorplan.outline import boundary_segments, wall_corners

__all__ = [
    "FloorplanError",
    "FloorplanWarning",
    "Room",
    "Door",
    "Floorplan",
    "DEFAULT_WALL_THICKNESS",
]

DEFAULT_WALL_THICKNESS = 0.15
# A door must come this close (m) to a room's polygon to count as touching it; rooms are
# usually drawn to the wall faces, doors across the wall centre line.
DOOR_TOUCH_TOL = 0.5


class FloorplanError(ValueError):
    """A floor plan that cannot be used; the message names the source and the feature."""


class FloorplanWarning(UserWarning):
    """A floor plan that loads but probably not as its author meant (the message says how to
    check and which option changes it)."""


@dataclass(frozen=True)
class Room:
    """A named room footprint."""

    name: str
    polygon: Polygon


@dataclass(frozen=True)
class Door:
    """A door: a segment across the opening ``(2, 2)`` and the rooms it joins (one or two)."""

    segment: np.ndarray
    rooms: tuple[str, ...]


def _finite(a) -> bool:
    return bool(np.all(np.isfinite(np.asarray(a, dtype=float))))


@dataclass(frozen=True, eq=False)
class Floorplan:
    """A 2D building model in frame B (metres).

    Attributes:
        walls: wall centre-line segments ``(W, 2, 2)``.
        thickness: wall thickness per segment ``(W,)``.
        wall_polygons: walls given directly as footprints (IFC cuts, GeoJSON polygons).
        rooms: named room polygons.
        doors: doors with the rooms they join.
        name: a short name for plots and tables.
        source: where it came from (a file path), used in error messages.
        offset: ``(2,)`` float64 local origin: plan (file) coordinates = the coordinates
            held here + ``offset``. Zero unless the loader moved a plan that lies far from
            the origin (georeferenced) next to it, so that float32 rasters and kernels keep
            their precision (``mfcl_jax.floorplan.origin``).
        walls_derived: True when the plan came with rooms only and its walls are the rooms'
            free boundaries (``passages.walls_from_rooms``).
        outside_unknown: True for an occupancy map: what lies outside its rooms and walls was
            never observed (unknown), which is no evidence of a wall; False for a plan,
            whose outside is outside the building (``raster.UNOBSERVED``).
        storeys: for several storeys laid side by side (``storeys.stack_storeys``), the
            ``Storeys`` that map its places back to the storeys; None for one storey.
    """

    walls: np.ndarray
    thickness: np.ndarray
    rooms: tuple[Room, ...]
    doors: tuple[Door, ...] = ()
    wall_polygons: tuple[Polygon, ...] = ()
    name: str = "floorplan"
    source: str = "<memory>"
    offset: np.ndarray = field(default_factory=lambda: np.zeros(2))
    walls_derived: bool = False
    outside_unknown: bool = False
    storeys: object = field(default=None, repr=False, compare=False)
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        walls = np.asarray(self.walls, dtype=np.float64).reshape(-1, 2, 2)
        thickness = self.thickness
        if walls.shape[0] == 0 and not self.wall_polygons and self.rooms:
            # a plan of rooms only: the rooms' free boundaries are its walls
            polys = [r.polygon for r in self.rooms if isinstance(r.polygon, Polygon)]
            walls = passages.walls_from_rooms(polys)
            thickness = passages.DERIVED_THICKNESS
            object.__setattr__(self, "walls_derived", bool(len(walls)))
        thick = np.broadcast_to(np.asarray(thickness, dtype=np.float64), (walls.shape[0],)).copy()
        object.__setattr__(self, "walls", walls)
        object.__setattr__(self, "thickness", thick)
        object.__setattr__(self, "rooms", tuple(self.rooms))
        object.__setattr__(self, "doors", tuple(self.doors))
        object.__setattr__(self, "wall_polygons", tuple(self.wall_polygons))
        offset = np.asarray(self.offset, dtype=np.float64).reshape(-1)
        if offset.shape != (2,) or not _finite(offset):
            raise FloorplanError(f"{self.source}: offset must be 2 finite numbers, got {offset}")
        object.__setattr__(self, "offset", offset)
        self._validate()

    # ------------------------------------------------------------------ validation
    def _fail(self, what: str) -> None:
        raise FloorplanError(f"{self.source}: {what}")

    def _validate(self) -> None:
        if not self.rooms:
            self._fail("floor plan has no rooms (need at least one 'room' polygon)")
        if self.walls.shape[0] == 0 and not self.wall_polygons:
            self._fail("floor plan has no walls")
        for i, (seg, t) in enumerate(zip(self.walls, self.thickness, strict=True)):
            if not _finite(seg):
                self._fail(f"wall #{i}: non-finite coordinates {seg.tolist()}")
            if not (np.isfinite(t) and t > 0):
                self._fail(f"wall #{i}: thickness must be a positive number, got {t!r}")
            if np.linalg.norm(seg[1] - seg[0]) <= 1e-9:
                self._fail(f"wall #{i}: zero-length segment at {seg[0].tolist()}")
        for i, poly in enumerate(self.wall_polygons):
            if not _finite(np.asarray(poly.exterior.coords)):
                self._fail(f"wall polygon #{i}: non-finite coordinates")
            if not poly.is_valid:
                self._fail(f"wall polygon #{i}: invalid polygon ({shapely.is_valid_reason(poly)})")
        names = set()
        for room in self.rooms:
            if not isinstance(room.polygon, Polygon):
                self._fail(f"room {room.name!r}: geometry must be a Polygon")
            if not _finite(np.asarray(room.polygon.exterior.coords)):
                self._fail(f"room {room.name!r}: non-finite coordinates")
            if not room.polygon.is_valid:
                reason = shapely.is_valid_reason(room.polygon)
                self._fail(f"room {room.name!r}: invalid polygon ({reason})")
            if room.polygon.area <= 0:
                self._fail(f"room {room.name!r}: polygon has zero area")
            if room.name in names:
                self._fail(f"room {room.name!r}: duplicate room name")
            names.add(room.name)
        for i, door in enumerate(self.doors):
            seg = np.asarray(door.segment, dtype=float)
            if seg.shape != (2, 2) or not _finite(seg):
                self._fail(f"door #{i}: segment must be two finite points, got {seg.tolist()}")
            if not 1 <= len(door.rooms) <= 2:
                self._fail(f"door #{i}: must join one or two rooms, got {list(door.rooms)}")
            for r in door.rooms:
                if r not in names:
                    self._fail(f"door #{i}: names unknown room {r!r}")
                d = self.room(r).polygon.distance(LineString(seg))
                if d > DOOR_TOUCH_TOL:
                    self._fail(f"door #{i}: does not touch room {r!r} (it is {d:.2f} m away)")

    # ------------------------------------------------------------------ lookup
    @property
    def room_names(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.rooms)

    def room(self, name: str) -> Room:
        for r in self.rooms:
            if r.name == name:
                return r
        raise KeyError(f"{self.source}: no room named {name!r}; rooms are {self.room_names}")

    def room_index(self, name: str) -> int:
        return self.room_names.index(name)

    @cached_property
    def adjacency(self) -> np.ndarray:
        """Room graph ``(R, R)`` bool (diagonal True): rooms joined by a door, or by an open
        passage where the plan marks none (``passages.open_adjacency``). A plan of rooms only
        marks no door and its walls are derived, so rooms facing each other across one may be
        joined anywhere on it: the walls are left out of the test."""
        n = len(self.rooms)
        polys = [r.polygon for r in self.rooms]
        walls = Polygon() if self.walls_derived else self.wall_solid
        adj = np.eye(n, dtype=bool) | passages.open_adjacency(polys, walls)
        for door in self.doors:
            if len(door.rooms) == 2:
                a, b = (self.room_index(r) for r in door.rooms)
                adj[a, b] = adj[b, a] = True
        return adj

    # ------------------------------------------------------------------ geometry
    @cached_property
    def wall_solid(self) -> Polygon | MultiPolygon:
        """Union of all wall footprints (segments buffered by half their thickness)."""
        # Square caps close L-junctions between centre lines (they extend each end by t/2).
        parts = [
            LineString(seg).buffer(t / 2.0, cap_style="square", join_style="mitre")
            for seg, t in zip(self.walls, self.thickness, strict=True)
        ]
        return unary_union(parts + list(self.wall_polygons))

    @cached_property
    def footprint(self) -> Polygon | MultiPolygon:
        """The inside of the building: rooms and walls, holes filled."""
        merged = unary_union([r.polygon for r in self.rooms] + [self.wall_solid])
        polys = merged.geoms if isinstance(merged, MultiPolygon) else [merged]
        return unary_union([Polygon(p.exterior) for p in polys])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the footprint."""
        return tuple(float(v) for v in self.footprint.bounds)

    @cached_property
    def wall_faces(self) -> np.ndarray:
        """Wall surface segments ``(F, 2, 2)``: the boundary of the wall solid."""
        return boundary_segments(self.wall_solid)

    @cached_property
    def corners(self) -> tuple[np.ndarray, np.ndarray]:
        """Wall-surface corners with their two edge directions, the most salient first.

        Corners are read off the wall-solid boundary simplified to ``CORNER_SIMPLIFY`` m (an
        occupancy map's cell staircases and scan jitter are not corners). Near-straight
        vertices (within 20 deg of 180) are dropped. A corner's salience is its shorter arm
        (edge length, m); at most ``MAX_CORNERS`` are kept, the most salient: a SLAM map's
        furniture blobs give thousands of tiny corners that would drown the structural ones
        in the front-end's vote budget. Plans with fewer corners keep them all. The constants
        and the code are in ``mfcl_jax.floorplan.outline`` (``wall_corners``).

        Returns:
            ``(points (C, 2), directions (C, 2))``: each corner's position and the angles (rad)
            of its two boundary edges, pointing away from the corner; most salient first.
        """
        return wall_corners(self.wall_solid)

    @cached_property
    def room_centroids(self) -> np.ndarray:
        """Room centroids ``(R, 2)``."""
        return np.asarray([[r.polygon.centroid.x, r.polygon.centroid.y] for r in self.rooms])

    @cached_property
    def room_areas(self) -> np.ndarray:
        return np.asarray([r.polygon.area for r in self.rooms])

    def room_at(self, xy) -> list[str | None]:
        """Room names at points ``(N, 2)`` (None outside every room)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        out: list[str | None] = [None] * len(xy)
        for r in reversed(self.rooms):
            inside = shapely.contains_xy(r.polygon, xy[:, 0], xy[:, 1])
            for i in np.flatnonzero(inside):
                out[i] = r.name
        return out

    def transformed(self, pose) -> Floorplan:
        """The same floor plan moved by a rigid motion ``pose = (x, y, theta)``."""
        x, y, th = (float(v) for v in pose)
        c, s = math.cos(th), math.sin(th)

        def tf(p):
            p = np.asarray(p, float)
            return np.stack(
                [c * p[..., 0] - s * p[..., 1] + x, s * p[..., 0] + c * p[..., 1] + y], -1
            )

        def tf_geom(g):
            return shapely.transform(g, lambda q: tf(q))

        return Floorplan(
            walls=tf(self.walls),
            thickness=self.thickness,
            rooms=tuple(Room(r.name, tf_geom(r.polygon)) for r in self.rooms),
            doors=tuple(Door(tf(d.segment), d.rooms) for d in self.doors),
            wall_polygons=tuple(tf_geom(p) for p in self.wall_polygons),
            name=self.name,
            source=self.source,
            offset=self.offset,
            walls_derived=self.walls_derived,
            outside_unknown=self.outside_unknown,
        )

    def rasterize(self, res: float = 0.10, margin: float = 1.0):
        """Rasters of this floor plan (see ``mfcl_jax.floorplan.raster.rasterize``)."""
        from mfcl_jax.floorplan.raster import rasterize

        key = (float(res), float(margin))
        if key not in self._cache:
            self._cache[key] = rasterize(self, res=res, margin=margin)
        return self._cache[key]
