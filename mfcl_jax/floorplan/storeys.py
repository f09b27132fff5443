"""A building of several storeys as one floor plan: the storeys side by side.

A robot that wakes up in a building does not know its floor. Rather than searching each
storey apart (one front-end and one decision layer per storey), the storeys are laid out next
to each other, ``GAP`` metres apart, in one plan: a placement of the robot's odometry frame in
that plan is a (storey, x, y, heading), the front-end and the layer weigh every storey in the
same search and the same compilation, and two storeys that look alike are, for the layer, two
places that look alike, which it already knows how to refuse.

Storeys that are congruent as a whole (the same walls and rooms, possibly moved or turned by
a quarter or half turn: the typical floors of a tower) are laid out once. That keeps a tower
of ten identical floors as cheap as two, and makes the answer on such a floor exact: no scan
can tell them apart, so a commit there names no storey (the layer reports
AMBIGUOUS(storey), ``decision.storey``). Storeys that differ anywhere get their own place
and the evidence (a lobby, a stair core, one room) decides between them.

``Storeys`` maps the stacked plan back: which storey a place belongs to (the ones that share
it), and the pose in that storey's own frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mfcl_jax.floorplan.model import Door, Floorplan, FloorplanError, Room
from mfcl_jax.se2 import compose_host, inverse_host

__all__ = ["GAP", "Storeys", "congruence", "stack_storeys"]

# Free space (m) between two storeys laid side by side: more than a submap's extent beyond a
# wall, so no window's points reach the next storey's walls through an exterior wall.
GAP = 12.0
# Two storeys are congruent when, after the motion, at most ``_WALL_AREA`` m2 of either's walls
# and ``_SHARE`` of their floor area lie farther than ``_TOL`` from the other's: a wall piece
# half a metre long that one storey has and the other lacks is a difference a LiDAR sees.
_SHARE = 0.01
_WALL_AREA = 0.05
_TOL = 0.10


def _apart(a, b) -> float:
    """Area (m2) of ``a`` and ``b`` (shapely) farther than ``_TOL`` from the other."""
    return a.difference(b.buffer(_TOL)).area + b.difference(a.buffer(_TOL)).area


def congruence(a: Floorplan, b: Floorplan) -> np.ndarray | None:
    """The motion ``g = (x, y, theta)`` with ``b = g(a)`` (walls and floor within tolerance),
    trying the identity and the quarter turns about the footprints' centroids; None when no
    such motion maps one storey onto the other."""
    if len(a.rooms) != len(b.rooms):
        return None
    fa, fb = a.footprint, b.footprint
    if abs(fa.area - fb.area) > _SHARE * (fa.area + fb.area):
        return None
    ca, cb = np.asarray(fa.centroid.coords[0]), np.asarray(fb.centroid.coords[0])
    for q in range(4):
        th = q * math.pi / 2
        c, s = math.cos(th), math.sin(th)
        t = cb - np.array([c * ca[0] - s * ca[1], s * ca[0] + c * ca[1]])
        g = np.array([t[0], t[1], th])
        moved = a.transformed(g)
        floor_ok = _apart(moved.footprint, fb) <= _SHARE * (fa.area + fb.area)
        if floor_ok and _apart(moved.wall_solid, b.wall_solid) <= _WALL_AREA:
            return g
    return None


@dataclass(frozen=True, eq=False)
class Storeys:
    """How a stacked plan maps back to its storeys.

    Attributes:
        names: the storeys, lowest first.
        tile: ``(S,)`` the place (tile) of each storey in the stacked plan; storeys sharing a
            tile are congruent.
        place: ``(S, 3)`` the motion from each storey's own frame to the stacked plan's.
        boxes: ``(T, 4)`` each tile's bounds in the stacked plan (xmin, ymin, xmax, ymax).
        source: where the storeys came from (error messages).
        given: the storey the user named (``--storey``), or -1: every storey is still weighed,
            a commit on the given storey's place names it (its congruent twins included), and
            a commit elsewhere is not reported (``robot.records``: the scans fit another
            storey).
    """

    names: tuple[str, ...]
    tile: np.ndarray
    place: np.ndarray
    boxes: np.ndarray
    source: str = "<memory>"
    given: int = -1

    @property
    def n_tiles(self) -> int:
        return int(self.boxes.shape[0])

    def group(self, t: int) -> list[int]:
        """The storeys laid out on tile ``t`` (congruent storeys share one)."""
        return [int(s) for s in np.flatnonzero(self.tile == t)]

    def shared(self, t: int) -> bool:
        """Several storeys on tile ``t`` and none of them the given one (which settles it)."""
        return len(self.group(t)) > 1 and self.given not in self.group(t)

    def tile_at(self, x: float, y: float) -> int:
        """The tile nearest ``(x, y)`` (stacked-plan frame; 0 inside its bounds), or -1 when
        every tile is ``GAP / 2`` or farther away."""
        b = self.boxes
        dx = np.maximum(np.maximum(b[:, 0] - x, x - b[:, 2]), 0.0)
        dy = np.maximum(np.maximum(b[:, 1] - y, y - b[:, 3]), 0.0)
        d = np.hypot(dx, dy)
        t = int(np.argmin(d))
        return t if d[t] < GAP / 2 else -1

    def to_storey(self, s: int, pose) -> tuple[float, float, float]:
        """A pose or anchor ``(x, y, theta)`` of the stacked plan in storey ``s``'s frame."""
        x, y, t = compose_host(inverse_host(self.place[s]), pose)
        return float(x), float(y), float(t)


def _tile_grid(sizes: np.ndarray) -> list[tuple[float, float]]:
    """Lower-left corners of tiles of ``sizes (T, 2)`` in a near-square grid, ``GAP`` apart."""
    w, h = float(sizes[:, 0].max()) + GAP, float(sizes[:, 1].max()) + GAP
    n = len(sizes)
    cols = max(1, min(n, round(math.sqrt(n * h / w))))
    return [((i % cols) * w, (i // cols) * h) for i in range(n)]


def stack_storeys(storeys: list[tuple[str, Floorplan]], name: str = "", source: str = "",
                  given: str | None = None):  # fmt: skip
    """Lays the storeys ``[(name, plan), ...]`` (lowest first) out as one plan (``given``:
    the storey the user named, ``Storeys.given``).

    Returns:
        ``(plan, Storeys)``: the stacked plan (rooms named ``"<storey>/<room>"``, its
        ``storeys`` attribute set) and the map back to the storeys.

    Raises:
        FloorplanError: no storey, two storeys of one name, or storeys with different local
            origins (``Floorplan.offset``).
    """
    if not storeys:
        raise FloorplanError(f"{source or name}: no storey to stack")
    names = [n for n, _ in storeys]
    if len(set(names)) != len(names):
        raise FloorplanError(f"{source or name}: two storeys share a name: {names}")
    offset = np.asarray(storeys[0][1].offset)
    for n, fp in storeys:
        if not np.allclose(fp.offset, offset):
            raise FloorplanError(
                f"{fp.source}: storey {n!r} has the local origin {fp.offset.tolist()}, "
                f"storey {names[0]!r} {offset.tolist()}: the storeys must share one frame"
            )
    reps: list[int] = []  # representative storey of each tile
    tile = np.zeros(len(storeys), np.int64)
    to_rep = np.zeros((len(storeys), 3))  # storey frame -> its representative's frame
    for i, (_, fp) in enumerate(storeys):
        for t, r in enumerate(reps):
            g = congruence(fp, storeys[r][1])
            if g is not None:
                tile[i], to_rep[i] = t, g
                break
        else:
            tile[i] = len(reps)
            reps.append(i)
    bounds = np.array([storeys[r][1].bounds for r in reps])
    corners = _tile_grid(bounds[:, 2:] - bounds[:, :2])
    shift = np.array(
        [[cx - b[0], cy - b[1], 0.0] for (cx, cy), b in zip(corners, bounds, strict=True)]
    )
    place = compose_host(shift[tile], to_rep)
    boxes = np.array([[b[0] + s[0], b[1] + s[1], b[2] + s[0], b[3] + s[1]]
                      for b, s in zip(bounds, shift, strict=True)])  # fmt: skip
    walls, thick, rooms, doors, polys = [], [], [], [], []
    for t, r in enumerate(reps):
        label = "+".join(names[s] for s in np.flatnonzero(tile == t))
        fp = storeys[r][1].transformed(shift[t])
        walls.append(fp.walls)
        thick.append(fp.thickness)
        polys.extend(fp.wall_polygons)
        rooms.extend(Room(f"{label}/{m.name}", m.polygon) for m in fp.rooms)
        doors.extend(Door(d.segment, tuple(f"{label}/{m}" for m in d.rooms)) for d in fp.doors)
    first = storeys[0][1]
    plan = Floorplan(
        walls=np.concatenate(walls).reshape(-1, 2, 2),
        thickness=np.concatenate(thick),
        rooms=tuple(rooms),
        doors=tuple(doors),
        wall_polygons=tuple(polys),
        name=name or first.name,
        source=source or first.source,
        offset=offset,
        walls_derived=any(fp.walls_derived for _, fp in storeys),
        outside_unknown=any(fp.outside_unknown for _, fp in storeys),
        storeys=Storeys(
            tuple(names),
            tile,
            place,
            boxes,
            source or first.source,
            -1 if given is None else names.index(given),
        ),
    )
    return plan, plan.storeys
