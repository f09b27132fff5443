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

Every statistic is an integer count accumulated along the trajectory, so a walk (``Walk``: the
counts and the last node visited) is extended by new samples (``extend_walk``) and gives
the same integers as walking the whole trajectory at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax.decision.maps import DOOR, OUTSIDE, DecisionMaps

__all__ = [
    "labels",
    "consistency_from_counts",
    "Walk",
    "start_walk",
    "extend_walk",
    "walk_labels",
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


def consistency_from_counts(n_valid, n_free, n_trans, n_ok):
    """``c = (n_free / n_valid) * ILLEGAL_FACTOR^(n_trans - n_ok)``; 0 without samples."""
    f = n_free.astype(jnp.float32) / jnp.maximum(n_valid, 1).astype(jnp.float32)
    v = jnp.power(jnp.float32(ILLEGAL_FACTOR), (n_trans - n_ok).astype(jnp.float32))
    return jnp.where(n_valid > 0, f * v, jnp.float32(0.0))


@dataclass(frozen=True)
class Walk:
    """What the gate remembers of a walk mapped by an anchor: the running counts and the last
    node visited, so that new samples extend it (leaves share the anchors' leading axes)."""

    counts: jax.Array  # (..., 4) int32 n_valid, n_free, n_trans, n_ok
    prev: jax.Array  # (...,) int32 last node visited, -1 before the first

    def consistency(self):
        c = self.counts
        return consistency_from_counts(c[..., 0], c[..., 1], c[..., 2], c[..., 3])


jax.tree_util.register_dataclass(Walk, data_fields=["counts", "prev"], meta_fields=[])


def start_walk(shape) -> Walk:
    return Walk(jnp.zeros((*shape, 4), jnp.int32), jnp.full(shape, -1, jnp.int32))


def extend_walk(maps: DecisionMaps, H, traj, valid, walk: Walk) -> Walk:
    """``walk`` extended by the samples ``traj (T, 3)`` (``valid (T,)``) mapped by anchors
    ``H (..., 3)``."""
    return walk_labels(maps, labels(maps, H, traj), valid, walk)


def walk_labels(maps: DecisionMaps, label, valid, walk: Walk) -> Walk:
    """``walk`` extended by samples with labels ``label (..., T)``.

    Nodes are room cells and ``OUTSIDE``; door and wall cells between two nodes are skipped;
    a change of node is a transition, legal along a graph edge. One sequential pass over the
    samples (``lax.scan``, vectorised over the anchors): on a CPU several times cheaper than
    a log-depth cumulative maximum.
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
        c = c + jnp.stack([v, free, trans, trans & edge], axis=-1).astype(jnp.int32)
        return (jnp.where(v & is_node, node, prev), c), None

    (prev, counts), _ = jax.lax.scan(step, (walk.prev, walk.counts), (lab_t, val_t))
    return Walk(counts, prev)
