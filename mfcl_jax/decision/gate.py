"""Feasibility gate: is the odometry trajectory, mapped by a candidate anchor, realizable?

Under anchor ``H`` the trajectory maps into the floor plan as ``H * traj_t``. Each mapped
sample gets a cell label from ``DecisionMaps.label``: a room index (``>= 0``), ``DOOR`` (free cell
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

import jax
import jax.numpy as jnp

from mfcl_jax.decision.maps import DOOR, OUTSIDE, DecisionMaps

__all__ = [
    "labels",
    "events",
    "walk_counts",
    "consistency_from_counts",
    "prefix_table",
    "consistency_at",
    "rooms_spanned",
]

ILLEGAL_FACTOR = 0.25


def labels(maps: DecisionMaps, H, traj):
    """Cell label of every trajectory sample mapped by every anchor.

    Args:
        maps: ``DecisionMaps``.
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


def events(maps: DecisionMaps, H, traj, valid):
    """Per-sample gate events of trajectories mapped by anchors.

    Args:
        maps: ``DecisionMaps``.
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


def walk_counts(maps: DecisionMaps, label, valid, keep_all: bool = False):
    """Running counts ``(n_valid, n_free, n_trans, n_ok)`` of the walk through ``label``.

    The same statistics as ``events`` summed over ``t``, accumulated by one sequential pass
    over the samples (``lax.scan``, vectorised over the anchors): on a CPU this is several
    times cheaper than the log-depth cumulative max / sums it replaces.

    Args:
        maps: ``DecisionMaps``.
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


def prefix_table(maps: DecisionMaps, H, traj, traj_mask, window_end):
    """Consistency of every anchor at every prefix, via cumulative counts.

    Args:
        maps: ``DecisionMaps``.
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


def consistency_at(maps: DecisionMaps, H, traj, traj_mask, end):
    """Consistency of anchors ``H (..., 3)`` on the samples ``t <= end``; equals the table."""
    t = jnp.arange(jnp.asarray(traj).shape[0])
    valid = jnp.asarray(traj_mask, bool) & (t <= end)
    return consistency_from_counts(*walk_counts(maps, labels(maps, H, traj), valid))


def rooms_spanned(maps: DecisionMaps, H, traj, traj_mask, end):
    """Number of distinct rooms visited by the trajectory mapped by ``H (3,)`` up to ``end``."""
    t = jnp.arange(jnp.asarray(traj).shape[0])
    label, valid, *_ = events(maps, H, traj, jnp.asarray(traj_mask, bool) & (t <= end))
    rooms = jnp.arange(maps.adjacency.shape[-1] - 1, dtype=label.dtype)
    seen = jnp.any((label[..., :, None] == rooms) & valid[..., :, None], axis=-2)
    return jnp.sum(seen, axis=-1).astype(jnp.int32)
