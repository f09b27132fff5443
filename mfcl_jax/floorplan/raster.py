"""Floor-plan rasters: the arrays every kernel samples.

``Rasters`` is a JAX pytree. Grids are indexed ``[iy, ix]``; cell ``(iy, ix)`` has its centre at
``origin + res * (ix + 0.5, iy + 0.5)``. ``res`` and the grid shape are static; the arrays are
leaves, so a batch of buildings can be padded to one shape bucket and stacked.

A cell is wall when its centre lies inside a wall solid, and also when the centre line of a wall
segment no thicker than a cell crosses it (``_thin_walls``). Without the second rule such a wall
can miss every cell centre and vanish from the rasters: the walls a plan of rooms only draws along
its rooms' free boundaries are 0.10 m thick, and where they sat on the grid's cell borders
10-50 % of their length was lost (measured on the benchmark's buildings), which left one side
of a ring corridor without its core wall and let a half-turn placement outscore the truth.
A straight wall thicker than a cell holds a cell centre in every row (or column) it crosses,
so the rule leaves such walls as they were (no nominal plan of the benchmark changes).

Outside the footprint a plan's cells are outdoors: a robot cannot stand there nor see into it
through a wall, and ``outside`` (their occupancy, what the path likelihood's obstacle field
reads there) is 1. An occupancy map's outside is different: cells never observed (unknown), a
region the map's author did not scan, not a wall; ``outside`` is then ``UNOBSERVED`` = 0.5, the
occupancy an unobserved cell of a log-odds grid holds. Measured on the benchmark's held-out log
maps, which lack some of the buildings' stretches: with outside cells read as walls, a path
through such a stretch paid ``log(1 - z_block)`` for each free sample there, and a wrong place
in the mapped part explained it up to 4 nats better than every other place; read as unknown,
no place more than a metre off leads by more than 2.15 nats (``docs/benchmark.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import shapely
from scipy import ndimage

__all__ = ["Rasters", "UNOBSERVED", "rasterize", "world_to_cell", "lookup", "bilinear", "pad_to"]

UNOBSERVED = 0.5  # occupancy of a never-observed cell (an occupancy map's outside)


@dataclass(frozen=True)
class Rasters:
    """Rasterised floor plan.

    Attributes:
        origin: ``(2,)`` world position of the grid's lower-left corner (m).
        dist: ``(H, W)`` float32 distance from the cell centre to the nearest wall solid (m).
        wall: ``(H, W)`` bool, inside a wall solid.
        room_id: ``(H, W)`` int32 room index, -1 outside every room.
        inside: ``(H, W)`` bool, inside the building footprint.
        adjacency: ``(R, R)`` bool room graph (doors), diagonal True.
        room_centroids: ``(R, 2)`` float32.
        outside: ``()`` float32 occupancy of the cells outside the footprint (and off the
            grid): 1 for a plan, ``UNOBSERVED`` for an occupancy map (module docstring).
        res: cell size (m), static.
    """

    origin: jax.Array
    dist: jax.Array
    wall: jax.Array
    room_id: jax.Array
    inside: jax.Array
    adjacency: jax.Array
    room_centroids: jax.Array
    outside: jax.Array = np.float32(1.0)
    res: float = 0.10

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.dist.shape[-2:])

    @property
    def n_rooms(self) -> int:
        return int(self.adjacency.shape[-1])

    def to_jax(self) -> Rasters:
        return jax.tree.map(jnp.asarray, self)

    def to_numpy(self) -> Rasters:
        return jax.tree.map(np.asarray, self)


jax.tree_util.register_dataclass(
    Rasters,
    data_fields=[
        "origin",
        "dist",
        "wall",
        "room_id",
        "inside",
        "adjacency",
        "room_centroids",
        "outside",
    ],
    meta_fields=["res"],
)


def rasterize(fp, res: float = 0.10, margin: float = 1.0) -> Rasters:
    """Rasterises a ``Floorplan`` at ``res`` metres, with ``margin`` metres around it.

    Returns:
        ``Rasters`` holding NumPy arrays (call ``.to_jax()`` to move them to the device).
    """
    xmin, ymin, xmax, ymax = fp.bounds
    x0, y0 = xmin - margin, ymin - margin
    w = int(math.ceil((xmax + margin - x0) / res))
    h = int(math.ceil((ymax + margin - y0) / res))
    cx = x0 + res * (np.arange(w) + 0.5)
    cy = y0 + res * (np.arange(h) + 0.5)
    gx, gy = np.meshgrid(cx, cy)
    gx, gy = gx.ravel(), gy.ravel()

    wall = shapely.contains_xy(fp.wall_solid, gx, gy).reshape(h, w)
    wall |= _thin_walls(fp, (x0, y0), res, (h, w))
    # Distance from free cells to the nearest wall cell, plus half a cell to the wall surface.
    dist = ndimage.distance_transform_edt(~wall) * res
    dist = np.where(wall, 0.0, np.maximum(dist - 0.5 * res, 0.0))
    room_id = np.full(h * w, -1, np.int32)
    for i, room in reversed(list(enumerate(fp.rooms))):
        room_id[shapely.contains_xy(room.polygon, gx, gy)] = i
    room_id = room_id.reshape(h, w)
    room_id = np.where(wall, -1, room_id).astype(np.int32)
    inside = shapely.contains_xy(fp.footprint, gx, gy).reshape(h, w)
    return Rasters(
        origin=np.asarray([x0, y0], np.float32),
        dist=dist.astype(np.float32),
        wall=wall,
        room_id=room_id,
        inside=inside,
        adjacency=np.asarray(fp.adjacency, bool),
        room_centroids=np.asarray(fp.room_centroids, np.float32),
        outside=np.float32(UNOBSERVED if fp.outside_unknown else 1.0),
        res=float(res),
    )


def _thin_walls(fp, origin, res: float, shape) -> np.ndarray:
    """``(H, W)`` bool: the cells crossed by the centre line of each wall segment no thicker
    than ``res``, sampled every quarter cell, so that no such wall is lost to the grid.

    Wall polygons (IFC cuts, GeoJSON polygons, the occupied pixels of a ROS map) carry no centre
    line and keep the cell-centre rule alone: marking a thin polygon's outline instead, tried,
    dilated single occupied pixels of the real logs' maps into blobs of up to four cells and
    moved 3 of the benchmark's 20 real-log runs (one commit lost, one a window later, one false
    commit exposed: ``docs/benchmark.md``), and no case showed a polygon's lost cells misleading
    the layer."""
    thin = res * (1 + 1e-6)
    out = np.zeros(shape, bool)
    for (a, b), t in zip(np.asarray(fp.walls).reshape(-1, 2, 2), fp.thickness, strict=True):
        if t > thin:
            continue
        n = max(2, int(math.ceil(4 * np.linalg.norm(b - a) / res)) + 1)
        u = np.linspace(0.0, 1.0, n)[:, None]
        p = a * (1 - u) + b * u
        ix = np.floor((p[:, 0] - origin[0]) / res).astype(np.int64)
        iy = np.floor((p[:, 1] - origin[1]) / res).astype(np.int64)
        ok = (ix >= 0) & (ix < shape[1]) & (iy >= 0) & (iy < shape[0])
        out[iy[ok], ix[ok]] = True
    return out


def pad_to(r: Rasters, shape: tuple[int, int], n_rooms: int | None = None) -> Rasters:
    """Pads rasters (NumPy) to a larger ``(H, W)`` bucket and room count, outside-valued.

    Padding cells are outside the building, not walls, far from walls, in no room.
    """
    h, w = r.shape
    H, W = shape
    if H < h or W < w:
        raise ValueError(f"pad_to: target {shape} smaller than rasters {r.shape}")
    pad = ((0, H - h), (0, W - w))
    far = float(np.max(r.dist)) if r.dist.size else 0.0
    R = r.n_rooms if n_rooms is None else n_rooms
    adj = np.zeros((R, R), bool)
    adj[: r.n_rooms, : r.n_rooms] = r.adjacency
    cen = np.full((R, 2), np.nan, np.float32)
    cen[: r.n_rooms] = r.room_centroids
    return Rasters(
        origin=np.asarray(r.origin),
        dist=np.pad(np.asarray(r.dist), pad, constant_values=far),
        wall=np.pad(np.asarray(r.wall), pad, constant_values=False),
        room_id=np.pad(np.asarray(r.room_id), pad, constant_values=-1),
        inside=np.pad(np.asarray(r.inside), pad, constant_values=False),
        adjacency=adj,
        room_centroids=cen,
        outside=np.asarray(r.outside, np.float32),
        res=r.res,
    )


def world_to_cell(r: Rasters, xy):
    """Continuous cell coordinates ``(*, 2)`` as ``(fx, fy)``: cell centres at integers."""
    return (xy - r.origin) / r.res - 0.5


def lookup(r: Rasters, grid, xy, fill):
    """Nearest-cell lookup of ``grid (H, W)`` at world points ``xy (*, 2)``.

    Points off the grid read ``fill``. Jit- and vmap-safe.
    """
    f = world_to_cell(r, xy)
    ix = jnp.round(f[..., 0]).astype(jnp.int32)
    iy = jnp.round(f[..., 1]).astype(jnp.int32)
    h, w = grid.shape[-2:]
    ok = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    val = grid[jnp.clip(iy, 0, h - 1), jnp.clip(ix, 0, w - 1)]
    return jnp.where(ok, val, fill)


def bilinear(r: Rasters, grid, xy, fill):
    """Bilinear sample of a float ``grid (H, W)`` at ``xy (*, 2)``; differentiable in ``xy``.

    Off-grid neighbours read ``fill``.
    """
    f = world_to_cell(r, xy)
    x0 = jnp.floor(f[..., 0])
    y0 = jnp.floor(f[..., 1])
    ax, ay = f[..., 0] - x0, f[..., 1] - y0
    h, w = grid.shape[-2:]

    def at(iy, ix):
        ok = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
        v = grid[jnp.clip(iy, 0, h - 1), jnp.clip(ix, 0, w - 1)]
        return jnp.where(ok, v, fill)

    x0i, y0i = x0.astype(jnp.int32), y0.astype(jnp.int32)
    v00, v01 = at(y0i, x0i), at(y0i, x0i + 1)
    v10, v11 = at(y0i + 1, x0i), at(y0i + 1, x0i + 1)
    return (1 - ay) * ((1 - ax) * v00 + ax * v01) + ay * ((1 - ax) * v10 + ax * v11)
