"""Feasibility gate: is the odometry trajectory, mapped by a candidate anchor, realizable?

Under anchor ``H`` the trajectory maps into the floor plan as ``H * traj_t``. Each mapped
sample gets a cell label from ``GateMaps.label``: a room index (``>= 0``), ``DOOR`` (free cell
inside the building that belongs to no room: door openings), ``WALL`` or ``OUTSIDE``.

Structural consistency over the samples ``t <= end`` of a prefix:

* free fraction ``f = n_free / n_valid``: samples on a room or door cell (walls and the
  outside are not free space);
* transitions: the "nodes" of the walk are room cells plus ``OUTSIDE`` (a pseudo-room joined
  only to rooms with an exterior door). Door and wall cells between two nodes are skipped, so
  a short gap at a door is ignored, but the two rooms on either side must be joined by a door
  (adjacency). A change of node is a transition; it is legal iff the room graph has that edge.
  Revisits (209 -> 208 -> 207 -> 208 -> 209) are all legal;
* consistency ``c = f * ILLEGAL_FACTOR^n_illegal`` in ``[0, 1]`` (factor 1/4): every illegal
  transition (a jump between non-adjacent rooms, leaving or re-entering the building through
  a wall) divides it by four, so with any ``tau_c > 0.25`` a single one fails the gate while
  ``c`` stays graded for threshold sweeps and the probe's ``gamma`` test. The gate admits
  iff ``c >= tau_c`` and never ranks: callers only
  compare ``c`` with thresholds.

Every statistic is an integer count accumulated along the trajectory, so the table of all
prefixes is one cumulative sum per anchor (``prefix_table``) and the
single-prefix evaluation (``consistency_at``) gives bit-identical numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.decision import symmetry
from mfcl_jax.floorplan.raster import Rasters

__all__ = [
    "DOOR",
    "WALL",
    "OUTSIDE",
    "GateMaps",
    "gate_maps",
    "labels",
    "events",
    "walk_counts",
    "consistency_from_counts",
    "prefix_table",
    "consistency_at",
    "rooms_spanned",
    "pad_maps",
]

DOOR, WALL, OUTSIDE = -1, -2, -3
ILLEGAL_FACTOR = 0.25


@dataclass(frozen=True)
class GateMaps:
    """What the gate and the lattice test read of a floor plan (a pytree; ``res`` static).

    Attributes:
        origin: ``(2,)`` grid lower-left corner (m).
        label: ``(H, W)`` int32 cell label: room index, ``DOOR``, ``WALL`` or ``OUTSIDE``.
        adjacency: ``(R + 1, R + 1)`` bool room graph; index ``R`` is the outside, joined to
            rooms with an exterior door.
        offsets: ``(P, 2)`` translations between congruent rooms (both signs), padded.
        offsets_mask: ``(P,)`` bool.
        generators: ``(G, 2)`` fundamental congruent-room offsets (one sign), padded.
        generators_mask: ``(G,)`` bool.
        motions: ``(M, 3)`` rotational self-motions ``g = (x, y, theta)`` of the building
            (rigid motions by a quarter turn mapping rooms onto distinct congruent rooms; see
            ``symmetry``), padded.
        motions_mask: ``(M,)`` bool.
        res: cell size (m).
    """

    origin: jax.Array
    label: jax.Array
    adjacency: jax.Array
    offsets: jax.Array
    offsets_mask: jax.Array
    generators: jax.Array
    generators_mask: jax.Array
    motions: jax.Array
    motions_mask: jax.Array
    res: float = 0.10

    @property
    def n_rooms(self) -> int:
        return int(self.adjacency.shape[-1]) - 1


jax.tree_util.register_dataclass(
    GateMaps,
    data_fields=[
        "origin",
        "label",
        "adjacency",
        "offsets",
        "offsets_mask",
        "generators",
        "generators_mask",
        "motions",
        "motions_mask",
    ],
    meta_fields=["res"],
)


def _congruent_offsets(r: Rasters, min_iou: float) -> np.ndarray:
    """Centroid offsets ``b - a`` between rooms whose cell sets match after translation."""
    rid = np.asarray(r.room_id)
    h, w = rid.shape
    cells, cents = [], []
    for i in range(r.n_rooms):
        iy, ix = np.nonzero(rid == i)
        cells.append((iy, ix))
        cents.append(np.array([ix.mean(), iy.mean()]) if ix.size else np.array([np.nan] * 2))
    out = []
    for a in range(r.n_rooms):
        for b in range(a + 1, r.n_rooms):
            (ya, xa), (yb, xb) = cells[a], cells[b]
            if (
                xa.size == 0
                or xb.size == 0
                or min(xa.size, xb.size) < min_iou * max(xa.size, xb.size)
            ):
                continue
            sx, sy = np.round(cents[a] - cents[b]).astype(int)
            key_a = ya.astype(np.int64) * (4 * w) + xa
            key_b = (yb + sy).astype(np.int64) * (4 * w) + (xb + sx)
            inter = np.intersect1d(key_a, key_b, assume_unique=True).size
            if inter / (xa.size + xb.size - inter) >= min_iou:
                off = (cents[b] - cents[a]) * r.res
                out.extend([off, -off])
    return np.asarray(out, np.float64).reshape(-1, 2)


def _fundamentals(offsets: np.ndarray, tol: float) -> np.ndarray:
    """Offsets (one sign) that are not integer multiples of a shorter offset."""
    canon = [o if (o[0] > 1e-6 or (abs(o[0]) <= 1e-6 and o[1] > 0)) else -o for o in offsets]
    canon = sorted(canon, key=lambda o: float(np.hypot(*o)))
    keep: list[np.ndarray] = []
    for o in canon:
        redundant = False
        for f in keep:
            n = round(float(np.dot(o, f) / np.dot(f, f)))
            if n >= 1 and np.hypot(*(o - n * f)) <= tol:
                redundant = True
                break
        if not redundant:
            keep.append(o)
    return np.asarray(keep, np.float64).reshape(-1, 2)


def _pad(a: np.ndarray, n: int, what: str = "room offsets") -> tuple[np.ndarray, np.ndarray]:
    if a.shape[0] > n:
        raise ValueError(f"gate_maps: {a.shape[0]} {what} exceed the capacity {n}")
    out = np.zeros((n, a.shape[1]), np.float32)
    out[: a.shape[0]] = a
    return out, np.arange(n) < a.shape[0]


def _congruent_offsets_poly(fp, min_iou: float) -> np.ndarray:
    """Centroid offsets ``b - a`` between rooms whose polygons match after translation (exact
    geometry, so an exact copy scores IoU 1 whatever its offset on the grid)."""
    from shapely import affinity

    polys = [room.polygon for room in fp.rooms]
    cents = [np.array([p.centroid.x, p.centroid.y]) for p in polys]
    out = []
    for a in range(len(polys)):
        for b in range(a + 1, len(polys)):
            pa, pb = polys[a], polys[b]
            if min(pa.area, pb.area) < min_iou * max(pa.area, pb.area):
                continue
            off = cents[b] - cents[a]
            moved = affinity.translate(pa, off[0], off[1])
            inter = moved.intersection(pb).area
            if inter / (pa.area + pb.area - inter) >= min_iou:
                out.extend([off, -off])
    return np.asarray(out, np.float64).reshape(-1, 2)


# Rooms whose footprints overlap this much after centroid alignment are treated as translated
# copies, so the alias probe guards their offsets. The paper's notion is exact congruence; we
# deliberately include near-copies (the stand-in rooms 207-209 reach IoU 0.91-0.96) because
# overlapping submap windows are correlated and can rendezvous on a one-room alias early
# (results/congruence.md measures a strict 0.98 against this default).
MIN_CONGRUENT_IOU = 0.8


def gate_maps(
    source,
    res: float = 0.10,
    min_iou: float = MIN_CONGRUENT_IOU,
    max_offsets: int | None = None,
    max_generators: int = 2,
    dedupe: float = 0.5,
    max_motions: int | None = None,
) -> GateMaps:
    """Builds ``GateMaps`` on the host from a ``Floorplan`` or ready ``Rasters``.

    Args:
        source: a ``Floorplan`` (exterior doors are read from its one-room doors) or
            ``Rasters`` (then the outside is joined to no room).
        res: raster resolution (m) when ``source`` is a floor plan.
        min_iou: IoU after centroid alignment above which two rooms are congruent (room
            polygons for a ``Floorplan``, cell sets for bare ``Rasters``).
        max_offsets: static capacity of the congruent-room offset list (default: sized to
            the building, a power of two >= 32).
        max_generators: static capacity of the fundamental offsets used by the alias probe.
        dedupe: offsets closer than this (m) are merged; also the multiple-test tolerance and
            the merge distance of rotational motions.
        max_motions: static capacity of the rotational self-motions probed as aliases
            (default: sized to the building, a power of two >= 8). Bare ``Rasters`` carry no
            room polygons and get none.

    Returns:
        ``GateMaps`` with NumPy leaves (``jax.tree.map(jnp.asarray, m)`` moves them).
    """
    exterior: set[int] = set()
    if isinstance(source, Rasters):
        r = source.to_numpy()
    elif hasattr(source, "rasterize"):
        r = source.rasterize(res=res).to_numpy()
        for d in source.doors:
            if len(d.rooms) == 1:
                exterior.add(source.room_index(d.rooms[0]))
    else:
        raise TypeError(f"gate_maps: expected a Floorplan or Rasters, got {type(source)!r}")
    n = r.n_rooms
    rid = np.asarray(r.room_id)
    label = np.where(
        rid >= 0, rid, np.where(np.asarray(r.wall), WALL, np.where(r.inside, DOOR, OUTSIDE))
    ).astype(np.int32)
    adj = np.zeros((n + 1, n + 1), bool)
    adj[:n, :n] = np.asarray(r.adjacency, bool)
    adj[n, n] = True
    for i in exterior:
        adj[i, n] = adj[n, i] = True
    if isinstance(source, Rasters):
        offs = _congruent_offsets(r, min_iou)
    else:
        offs = _congruent_offsets_poly(source, min_iou)
    uniq: list[np.ndarray] = []
    for o in offs:
        if all(np.hypot(*(o - u)) > dedupe for u in uniq):
            uniq.append(o)
    offs = np.asarray(uniq, np.float64).reshape(-1, 2)
    gens = _fundamentals(offs, dedupe)[:max_generators]
    if max_offsets is None:
        max_offsets = 32
        while max_offsets < len(offs):
            max_offsets *= 2
    if isinstance(source, Rasters):
        mots = np.zeros((0, 3))
    else:
        mots, _ = symmetry.rotational_motions(source, min_iou, dedupe)
    if max_motions is None:
        max_motions = 8
        while max_motions < len(mots):
            max_motions *= 2
    o, om = _pad(offs, max_offsets)
    g, gm = _pad(gens, max_generators)
    mo, mm = _pad(mots, max_motions, "rotational motions")
    origin = np.asarray(r.origin, np.float32)
    return GateMaps(origin, label, adj, o, om, g, gm, mo, mm, float(r.res))


def labels(maps: GateMaps, H, traj):
    """Cell label of every trajectory sample mapped by every anchor.

    Args:
        maps: ``GateMaps``.
        H: ``(..., 3)`` anchors.
        traj: ``(T, 3)`` odometry poses in L.

    Returns:
        ``(..., T)`` int32 labels (``OUTSIDE`` off the grid).
    """
    H, traj = jnp.asarray(H), jnp.asarray(traj)
    # Same arithmetic as se2.apply + raster.lookup, but the heading trig is taken once per
    # anchor and the raster is read by a flat 1-D gather (several times faster on a CPU).
    c, s = jnp.cos(H[..., 2:3]), jnp.sin(H[..., 2:3])
    vx, vy = traj[:, 0], traj[:, 1]
    x = c * vx - s * vy + H[..., 0:1]
    y = s * vx + c * vy + H[..., 1:2]
    ix = jnp.round((x - maps.origin[0]) / maps.res - 0.5).astype(jnp.int32)
    iy = jnp.round((y - maps.origin[1]) / maps.res - 0.5).astype(jnp.int32)
    h, w = maps.label.shape[-2:]
    ok = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    flat = jnp.where(ok, iy * w + ix, 0)
    val = maps.label.reshape(-1).at[flat].get(mode="promise_in_bounds")
    return jnp.where(ok, val, OUTSIDE)


def events(maps: GateMaps, H, traj, valid):
    """Per-sample gate events of trajectories mapped by anchors.

    Args:
        maps: ``GateMaps``.
        H: ``(..., 3)`` anchors.
        traj: ``(T, 3)`` odometry poses in L.
        valid: ``(T,)`` bool samples to use.

    Returns:
        ``(label, valid, free, trans, ok)``, each ``(..., T)``: cell label, sample validity,
        free-space sample, node change, node change along a graph edge.
    """
    label = labels(maps, H, traj)
    valid = jnp.broadcast_to(jnp.asarray(valid, bool), label.shape)
    n_node = maps.adjacency.shape[-1]
    n_out = n_node - 1
    is_node = (label >= 0) | (label == OUTSIDE)
    node = jnp.where(label >= 0, label, n_out)
    t = jnp.arange(label.shape[-1], dtype=jnp.int32)
    last = jax.lax.cummax(jnp.where(valid & is_node, t, -1), axis=label.ndim - 1)
    prev = jnp.concatenate([jnp.full_like(last[..., :1], -1), last[..., :-1]], axis=-1)
    prev_node = jnp.take_along_axis(node, jnp.maximum(prev, 0), axis=-1)
    trans = valid & is_node & (prev >= 0) & (prev_node != node)
    adj = maps.adjacency.reshape(-1).at[prev_node * n_node + node].get(mode="promise_in_bounds")
    ok = trans & adj
    free = valid & ((label >= 0) | (label == DOOR))
    return label, valid, free, trans, ok


def walk_counts(maps: GateMaps, label, valid, keep_all: bool = False):
    """Running counts ``(n_valid, n_free, n_trans, n_ok)`` of the walk through ``label``.

    The same statistics as ``events`` summed over ``t``, accumulated by one sequential pass
    over the samples (``lax.scan``, vectorised over the anchors): on a CPU this is several
    times cheaper than the log-depth cumulative max / sums it replaces.

    Args:
        maps: ``GateMaps``.
        label: ``(..., T)`` labels (``labels``); valid: ``(T,)`` or ``(..., T)`` bool.
        keep_all: return the counts after every sample instead of after the last one.

    Returns:
        ``(4, ...)`` int32 counts, or ``(T, 4, ...)`` with ``keep_all``.
    """
    n_node = maps.adjacency.shape[-1]
    adj = maps.adjacency.reshape(-1)
    lab_t = jnp.moveaxis(label, -1, 0)
    val_t = jnp.moveaxis(jnp.broadcast_to(jnp.asarray(valid, bool), label.shape), -1, 0)

    def step(carry, x):
        prev, c = carry  # last node visited (-1: none yet), counts so far
        lab, v = x
        is_node = (lab >= 0) | (lab == OUTSIDE)
        node = jnp.where(lab >= 0, lab, n_node - 1)
        trans = v & is_node & (prev >= 0) & (prev != node)
        edge = adj.at[jnp.maximum(prev, 0) * n_node + node].get(mode="promise_in_bounds")
        free = v & ((lab >= 0) | (lab == DOOR))
        c = c + jnp.stack([v, free, trans, trans & edge]).astype(jnp.int32)
        prev = jnp.where(v & is_node, node, prev)
        return (prev, c), (c if keep_all else None)

    shape = label.shape[:-1]
    init = (jnp.full(shape, -1, jnp.int32), jnp.zeros((4, *shape), jnp.int32))
    (_, c), cs = jax.lax.scan(step, init, (lab_t, val_t))
    return cs if keep_all else c


def consistency_from_counts(n_valid, n_free, n_trans, n_ok):
    """``c = (n_free / n_valid) * ILLEGAL_FACTOR^(n_trans - n_ok)``; 0 without samples."""
    f = n_free.astype(jnp.float32) / jnp.maximum(n_valid, 1).astype(jnp.float32)
    v = jnp.power(jnp.float32(ILLEGAL_FACTOR), (n_trans - n_ok).astype(jnp.float32))
    return jnp.where(n_valid > 0, f * v, jnp.float32(0.0))


def prefix_table(maps: GateMaps, H, traj, traj_mask, window_end):
    """Consistency of every anchor at every prefix, via cumulative counts.

    Args:
        maps: ``GateMaps``.
        H: ``(..., 3)`` anchors, e.g. ``(K, J, 3)``.
        traj: ``(T, 3)``; traj_mask: ``(T,)``.
        window_end: ``(Kp,)`` int32 last sample index of each prefix.

    Returns:
        ``(..., Kp)`` float32 consistency.
    """
    label = labels(maps, H, traj)
    cs = walk_counts(maps, label, traj_mask, keep_all=True)  # (T, 4, ...)
    end = jnp.clip(jnp.asarray(window_end), 0, label.shape[-1] - 1)
    counts = jnp.moveaxis(cs[end], 0, -1)  # (4, ..., Kp)
    return consistency_from_counts(*counts)


def consistency_at(maps: GateMaps, H, traj, traj_mask, end):
    """Consistency of anchors ``H (..., 3)`` on the samples ``t <= end``; equals the table."""
    t = jnp.arange(jnp.asarray(traj).shape[0])
    valid = jnp.asarray(traj_mask, bool) & (t <= end)
    return consistency_from_counts(*walk_counts(maps, labels(maps, H, traj), valid))


def rooms_spanned(maps: GateMaps, H, traj, traj_mask, end):
    """Number of distinct rooms visited by the trajectory mapped by ``H (3,)`` up to ``end``."""
    t = jnp.arange(jnp.asarray(traj).shape[0])
    label, valid, *_ = events(maps, H, traj, jnp.asarray(traj_mask, bool) & (t <= end))
    rooms = jnp.arange(maps.adjacency.shape[-1] - 1, dtype=label.dtype)
    seen = jnp.any((label[..., :, None] == rooms) & valid[..., :, None], axis=-2)
    return jnp.sum(seen, axis=-1).astype(jnp.int32)


def pad_maps(
    m: GateMaps, shape: tuple[int, int], n_rooms: int | None = None, n_motions: int | None = None
) -> GateMaps:
    """Pads host ``GateMaps`` to a grid bucket ``(H, W)`` and a room count (outside stays last).

    Padding cells are ``OUTSIDE``; padded rooms are isolated; ``n_motions`` (default: kept)
    pads the rotational-motion capacity. Lets runs of different buildings (or tests) share one
    compiled shape.
    """
    h, w = np.asarray(m.label).shape
    H, W = shape
    n = m.n_rooms
    R = n if n_rooms is None else n_rooms
    if H < h or W < w or R < n:
        raise ValueError(f"pad_maps: target {shape}, {R} rooms smaller than {(h, w)}, {n} rooms")
    label = np.pad(np.asarray(m.label), ((0, H - h), (0, W - w)), constant_values=OUTSIDE)
    adj = np.zeros((R + 1, R + 1), bool)
    a = np.asarray(m.adjacency)
    adj[:n, :n] = a[:n, :n]
    adj[:n, R] = a[:n, n]
    adj[R, :n] = a[n, :n]
    adj[R, R] = True
    adj[np.arange(R), np.arange(R)] = True
    mo, mm = np.asarray(m.motions), np.asarray(m.motions_mask)
    M = mo.shape[0] if n_motions is None else n_motions
    if M < int(mm.sum()):
        raise ValueError(f"pad_maps: {int(mm.sum())} rotational motions exceed n_motions={M}")
    mo, mm = _pad(mo[mm], M, "rotational motions")
    return GateMaps(
        np.asarray(m.origin),
        label,
        adj,
        *(np.asarray(x) for x in (m.offsets, m.offsets_mask, m.generators, m.generators_mask)),
        mo,
        mm,
        m.res,
    )
