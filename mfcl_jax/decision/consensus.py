"""Density-immune consensus over per-submap champions.

* Champion of window ``w`` at prefix ``k``: its highest-scoring admitted candidate (admitted =
  valid, ``w <= k``, score above the floor, gate passed when the gate is on). Lower-scored
  candidates never enter, so flooding a submap below its champion changes nothing.
* Grouping is leader clustering: champions are visited in a fixed order (score descending,
  then window index); each joins the existing group whose *leader* (first member) is within
  both ``delta_xy`` and ``delta_theta``, the nearest in planar distance among several, or
  opens a new group. The tolerances grow with the odometric distance travelled between the
  member's window and the leader's (``drift_xy`` per metre, ``drift_theta`` rad per metre):
  odometry drifts, so one place's anchor estimated 40 m apart differs by more than a window's
  noise. Distance to the group anchor, never chaining through members; the two
  tolerances are tested separately, never mixed into one norm.
* ``B_m`` counts INDEPENDENT evidence: the largest number of the group's champions whose
  windows share no scan (windows are intervals of keyframes; the greedy earliest-ending choice
  is optimal for intervals, and windows end in index order). With ``d_s = 6`` m, a 2 m step
  and 0.25 m keyframes, window ``k + 3`` starts on window ``k``'s last scan and ``k + 4`` is
  the first disjoint one, so the overlapping windows that saw one 10-12 m stretch count
  once: the champions counted are computed from disjoint scan sets, which is the
  independence Proposition 1 assumes. The raw member count is kept as
  ``size``. The winner has the largest ``B_m``, ties to the larger raw group, then to the group
  with the higher-scored leader; ``margin = B1 - B2``.
* Two means of the winner (arithmetic xy, circular yaw), because odometry drifts and an anchor
  is exact only near the time it was estimated:

  - ``t_all``, the mean of *all* the winner's champions (the paper's ``T*``). It is the group's
    centre: ``spread`` (largest planar distance of a member to it) and the group anchors that
    the lattice test compares are all-member means.
  - ``t_star``, the *reported* anchor: the mean of the winner's ``recent`` most recent
    champions (largest window indices; ``recent <= 0`` takes them all, i.e. ``t_all``). It is
    the anchor that is committed, so the winner's gate, its rooms spanned and the alias probe
    use it too. Early, drifted members keep counting in ``B_m`` but cannot pull it away.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2

__all__ = ["Champions", "Groups", "champions", "group", "leader_groups", "disjoint_count"]


@dataclass(frozen=True)
class Champions:
    """Per-window champions at one prefix. Shapes ``(K, ...)``."""

    pose: jax.Array  # (K, 3)
    score: jax.Array  # (K,)
    has: jax.Array  # (K,) bool
    index: jax.Array  # (K,) int32 candidate index j*


@dataclass(frozen=True)
class Groups:
    """Consensus groups at one prefix (group axis padded to ``K``)."""

    assign: jax.Array  # (K,) int32 group of each champion, -1 if none
    size: jax.Array  # (K,) int32 raw member count per group slot
    indep: jax.Array  # (K,) int32 B_m: members in pairwise scan-disjoint windows
    anchor: jax.Array  # (K, 3) mean pose of each group
    n_groups: jax.Array  # () int32
    winner: jax.Array  # () int32
    b1: jax.Array
    b2: jax.Array
    margin: jax.Array
    t_star: jax.Array  # (3,) reported anchor: mean of the winner's most recent champions
    spread: jax.Array  # () max planar distance of winner members to t_all
    t_all: jax.Array  # (3,) mean of all the winner's champions (the group centre)
    seen: jax.Array  # () int32 scan-disjoint windows with a champion, any group (saturation)


for _cls in (Champions, Groups):
    jax.tree_util.register_dataclass(
        _cls, data_fields=list(_cls.__dataclass_fields__), meta_fields=[]
    )


def champions(H, score, admitted) -> Champions:
    """Top-1 admitted candidate of each window.

    Args:
        H: ``(K, J, 3)`` anchors; score: ``(K, J)``; admitted: ``(K, J)`` bool.
    """
    s = jnp.where(admitted, score, -jnp.inf)
    j = jnp.argmax(s, axis=-1).astype(jnp.int32)
    pose = jnp.take_along_axis(H, j[:, None, None], axis=1)[:, 0]
    has = jnp.any(admitted, axis=-1)
    best = jnp.take_along_axis(score, j[:, None], axis=1)[:, 0]
    return Champions(pose, jnp.where(has, best, jnp.zeros_like(best)), has, j)


def leader_groups(pose, weight, has, delta_xy, delta_theta, s=None, grow_xy=0.0, grow_th=0.0):
    """Leader clustering of ``pose (M, 3)`` visited by ``weight`` descending (ties: index).

    With ``s (M,)`` (odometric travelled distance of each pose's window) the tolerances grow
    with the distance travelled between a pose and the leader it is compared with:
    ``delta_xy + grow_xy |s - s_leader|`` and ``delta_theta + grow_th |s - s_leader|``, so
    anchors estimated far apart along the path, which odometry drift separates, stay together.

    Returns:
        ``(assign (M,) int32, leaders (M, 3), n_groups ())``.
    """
    pose, weight, has = jnp.asarray(pose), jnp.asarray(weight), jnp.asarray(has, bool)
    m = pose.shape[0]
    s = jnp.zeros(m, pose.dtype) if s is None else jnp.asarray(s, pose.dtype)
    key = jnp.where(has, weight, -jnp.inf)
    order = jnp.lexsort((jnp.arange(m), -key))
    slots = jnp.arange(m)

    def body(i, carry):
        assign, leaders, lead_s, ng = carry
        c = order[i]
        p = pose[c]
        dxy, dth = se2.distance_pair(leaders, p)
        ds = jnp.abs(lead_s - s[c])
        within = (dxy <= delta_xy + grow_xy * ds) & (dth <= delta_theta + grow_th * ds)
        within &= slots < ng
        join = jnp.argmin(jnp.where(within, dxy, jnp.inf)).astype(jnp.int32)
        found = jnp.any(within)
        g = jnp.where(found, join, ng)
        g = jnp.where(has[c], g, -1)
        new = has[c] & ~found
        here = new & (slots == ng)
        leaders = jnp.where(here[:, None], p, leaders)
        lead_s = jnp.where(here, s[c], lead_s)
        return assign.at[c].set(g), leaders, lead_s, ng + new.astype(jnp.int32)

    init = (jnp.full((m,), -1, jnp.int32), jnp.zeros_like(pose), jnp.zeros_like(s), jnp.int32(0))
    assign, leaders, _, ng = jax.lax.fori_loop(0, m, body, init)
    return assign, leaders, ng


def disjoint_count(onehot, start, end):
    """Per group, the most members whose windows pairwise share no scan.

    Args:
        onehot: ``(G, K)`` bool membership; start, end: ``(K,)`` keyframe bounds of the windows
            (inclusive), non-decreasing in ``k``.

    Returns:
        ``(G,)`` int32.
    """

    def step(carry, x):
        last, n = carry
        m, s, e = x
        take = m & (s > last)
        return (jnp.where(take, e, last), n + take.astype(jnp.int32)), None

    g = onehot.shape[0]
    start, end = start.astype(jnp.int32), end.astype(jnp.int32)
    init = (jnp.full((g,), -1, jnp.int32), jnp.zeros((g,), jnp.int32))
    (_, n), _ = jax.lax.scan(step, init, (onehot.T, start, end))
    return n


def group(
    ch: Champions, delta_xy, delta_theta, recent=0, start=None, end=None, s=None, grow=(0.0, 0.0)
) -> Groups:
    """Groups champions and summarises consensus (see the module docstring).

    Args:
        ch: ``Champions`` of one prefix (window order along the first axis).
        delta_xy, delta_theta: grouping tolerances (traced).
        recent: ``()`` number of most recent winner champions averaged into ``t_star``
            (traced; ``<= 0``: all of them).
        start, end: ``(K,)`` keyframe bounds of the windows; ``None`` treats every window as
            disjoint from the others (``B_m`` = member count).
        s: ``(K,)`` travelled distance at each window's end, and ``grow = (grow_xy,
            grow_theta)`` the tolerances' growth per metre between windows (odometry drift).
    """
    k = ch.pose.shape[0]
    assign, _, ng = leader_groups(
        ch.pose, ch.score, ch.has, delta_xy, delta_theta, s, grow[0], grow[1]
    )
    onehot = (assign[None, :] == jnp.arange(k)[:, None]) & ch.has[None, :]  # (G, K)
    size = jnp.sum(onehot, axis=1).astype(jnp.int32)
    if start is None:
        indep = size
        seen = jnp.sum(ch.has).astype(jnp.int32)
    else:
        start, end = jnp.asarray(start), jnp.asarray(end)
        both = jnp.concatenate([onehot, ch.has[None]], axis=0)
        counts = disjoint_count(both, start, end)
        indep, seen = counts[:-1], counts[-1]
    anchor = se2.mean_pose(jnp.broadcast_to(ch.pose, (k, k, 3)), onehot.astype(ch.pose.dtype))
    winner = jnp.argmax(indep * (k + 1) + size).astype(jnp.int32)  # first max: opened first
    b1 = indep[winner]
    b2 = jnp.max(jnp.where(jnp.arange(k) == winner, 0, indep))
    members = onehot[winner]
    t_all = anchor[winner]
    dxy, _ = se2.distance_pair(ch.pose, t_all)
    spread = jnp.max(jnp.where(members, dxy, 0.0))
    # members after window w (window order = time order): rank 0 is the latest member
    later = jnp.cumsum(members[::-1].astype(jnp.int32))[::-1] - members.astype(jnp.int32)
    recent = jnp.asarray(recent, jnp.float32)
    take = members & ((later.astype(jnp.float32) < recent) | (recent <= 0))
    t_star = se2.mean_pose(ch.pose, take.astype(ch.pose.dtype))
    return Groups(
        assign, size, indep, anchor, ng, winner, b1, b2, b1 - b2, t_star, spread, t_all, seen
    )
