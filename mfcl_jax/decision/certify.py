"""Certify before commit: does ``T*`` explain the path seen so far clearly better than every
competing explanation?

The evidence is the submaps themselves. Every window of the prefix is re-scored under the
winner ``T*`` and under each competitor ``C`` with the front-end's verification score
(``frontend.verify.score``: points near plan walls rewarded, rays through plan walls or out of
the building penalised), the window placed at ``T* X_w`` resp. ``C X_w``. Only the windows of
a scan-disjoint chain ending at the prefix are used (each scan counted once, as in the
consensus), compacted into ``n_windows`` slots.

Competitors: the probe's aliases of ``T*`` (period-shifted copies and rotated images by the
building's self-motions), every other consensus group's anchor, each window's best
candidate outside the winner's neighbourhood (the runner-up explanation of that window, which
the top-1 consensus never sees), and the rivals of the whole path found by the global search
where a commit was about to happen (``rivals``). A competitor that places the robot within
``CORRECT`` of where ``T*`` does is the same answer and is not a competitor.

Fair comparison. The score's kernel is sharp (``cert_sigma``, 7 cm), so a pose a few
centimetres off a window loses much of its score. ``T*`` is an average of recent champions
and each window's anchor moves with the odometry's drift, while a runner-up candidate or a
rival of the global search is fitted to its own window or path: compared as they come, the
less-fitted explanation loses by its misfit, not by the walls. So every explanation
(``T*`` included) is scored in every window at its best fit within a few centimetres and
tenths of a degree (``REFINE``: two rounds of steps along each axis, 13 poses), the same for all.
Measured before this rule: a half-turn rival of a symmetric building was "contradicted" by
one window (advantage 0.20) and "favoured" by another (-0.08), both by misfit; fitted, it
ties in both (0.05, 0.01). Each ray also carries ``FREE_PER_RAY`` free-space samples (at 0,
1/4, 1/2 and 3/4 of its free length), so an explanation under which the robot saw through
a plan wall is penalised, not only one that puts the sensor in a wall.

Per competitor the advantage ``adv_w = s_w(T*) - s_w(C)`` gives two numbers, the largest and
the smallest advantage over the windows; ``finish`` compares them with the margin
``cert_margin`` (a knob): ``C`` is ruled out when some window contradicts it
(``max adv >= margin``) and none favours it (``min adv > -margin``); ``T*`` is dominated when
some competitor is favoured somewhere and contradicted nowhere. Otherwise ``C`` stays a live
explanation and the decision is AMBIGUOUS with ``C``'s kind (relative to ``T*``: a translation
with its period, a rotation, or multimodal; a mirrored wing shows up as one of these, since a
reflection is not a rigid motion).

Sub-window evidence (``CERT_BLOCKS``). A competitor that differs from ``T*`` along part of a
window only (one doorway, the far wall of one office, a bay's end) is diluted in the window's
mean: measured on the benchmark's offices, such a competitor lost by 0.014-0.030 per window
(margin 0.05) and by 0.09 on the sixth of the window where the walls differ. So each window's
evidence points, which keep the scans' order (``batch.evidence_sample``), are also scored in
``CERT_BLOCKS`` contiguous blocks at the window's fitted pose, and a block's advantage counts
toward ``max adv`` (contradiction) at equal confidence with a whole window of
``MARGIN_POINTS`` points: a block holds ``P / CERT_BLOCKS`` points, so its advantage is divided
by ``sqrt(CERT_BLOCKS * MARGIN_POINTS / P)`` (2 for the default 128 points in 4 blocks, i.e.
a block must beat the margin twice over). Favouring a competitor (``min adv``) stays a
whole-window test: a block can rule a competitor out, never rule ``T*`` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.frontend import verify

__all__ = [
    "CertStats",
    "chain",
    "competitors",
    "certify",
    "relation",
    "CERT_BLOCKS",
    "CORRECT",
    "MARGIN_POINTS",
]

CORRECT = (1.0, math.radians(5.0))  # same answer: the robot placed within 1 m and 5 deg
# Every explanation is scored at its best fit to each window: two rounds of one step either way
# along x, y and the heading (6 cm / 0.6 deg, then 2 cm / 0.2 deg; see the module docstring).
REFINE = ((0.06, math.radians(0.6)), (0.02, math.radians(0.2)))
FREE_PER_RAY = 4  # free-space samples per ray (a ray through a plan wall is penalised)
CERT_BLOCKS = 4  # contiguous blocks of each window's evidence, each tested on its own
MARGIN_POINTS = 128  # evidence points per window that ``cert_margin`` was set for


@dataclass(frozen=True)
class CertStats:
    """Per competitor: the anchor, whether it is a competitor, and its advantage extremes."""

    anchor: jax.Array  # (C, 3)
    valid: jax.Array  # (C,) bool: a competitor distinct from T* (placing the robot elsewhere)
    max_adv: jax.Array  # (C,) largest  s(T*) - s(C) over the windows used and their blocks
    min_adv: jax.Array  # (C,) smallest s(T*) - s(C)
    n_windows: jax.Array  # () windows used


jax.tree_util.register_dataclass(
    CertStats, data_fields=list(CertStats.__dataclass_fields__), meta_fields=[]
)


def chain(k, start, end, valid, n_slots: int):
    """Scan-disjoint windows ending at prefix ``k``, latest first, compacted.

    Args:
        k: ``()`` prefix; start, end: ``(K,)`` keyframe bounds; valid: ``(K,)`` windows with
            evidence.
        n_slots: static number of slots returned.

    Returns:
        ``(idx (n_slots,) int32, ok (n_slots,) bool)``.
    """
    kk = start.shape[0]

    def body(i, carry):
        w = k - i
        take, limit = carry
        ok = (w >= 0) & valid[jnp.maximum(w, 0)] & (end[jnp.maximum(w, 0)] < limit)
        take = take.at[jnp.maximum(w, 0)].set(take[jnp.maximum(w, 0)] | ok)
        return take, jnp.where(ok, start[jnp.maximum(w, 0)], limit)

    big = jnp.iinfo(jnp.int32).max
    take, _ = jax.lax.fori_loop(0, kk, body, (jnp.zeros(kk, bool), jnp.int32(big)))
    order = jnp.argsort(jnp.where(take, -jnp.arange(kk), kk))[:n_slots]
    return order.astype(jnp.int32), take[order]


def competitors(t_star, aliases, aliases_ok, groups, groups_ok, H, score, visible, x_now,
                rivals=None, rivals_ok=None):  # fmt: skip
    """The competitor anchors at one prefix.

    Args:
        t_star: ``(3,)``; aliases: ``(A, 3)`` with ``aliases_ok``; groups: ``(G, 3)`` other
            groups' anchors with ``groups_ok``; H, score, visible: ``(K, J, ...)`` candidates of
            the prefix; x_now: ``(3,)`` the odometry pose at the prefix; rivals: ``(E, 3)``
            placements of the whole path found by the global search (``rivals``) with
            ``rivals_ok`` (those found at or before this prefix), or None.

    Returns:
        ``(anchors (A + G + K [+ E], 3), ok)``: each window's runner-up is its best
        visible candidate that places the robot (now) farther than ``CORRECT`` from where
        ``T*`` does: a candidate 1-1.5 m off shares the winner's consensus group, yet it is a
        different answer, so it must be ruled out like any other.
    """
    here = se2.compose(t_star, x_now)
    dxy, dth = se2.distance_pair(se2.compose(H, x_now), here)
    outside = visible & ((dxy > CORRECT[0]) | (dth > CORRECT[1]))
    s = jnp.where(outside, score, -jnp.inf)
    j = jnp.argmax(s, axis=1)
    runner = jnp.take_along_axis(H, j[:, None, None], axis=1)[:, 0]
    runner_ok = jnp.any(outside, axis=1)
    anchors = jnp.concatenate([aliases, groups, runner], axis=0)
    ok = jnp.concatenate([aliases_ok, groups_ok, runner_ok])
    if rivals is not None:
        anchors = jnp.concatenate([anchors, rivals.astype(anchors.dtype)], axis=0)
        ok = jnp.concatenate([ok, rivals_ok])
    return anchors, ok


def _window_scores(poses, pts, org, pmask, maps, sigma, lam, n_free: int, steps=REFINE,
                   n_blocks: int = CERT_BLOCKS):  # fmt: skip
    """Verification score of each window (rows) under each pose ``(W, C, 3)``, each pose at
    its best fit: per round of ``steps`` (``(step_xy, step_theta)``), a step either way along
    x, y and the heading in turn (in the window's frame), each kept where it scores higher.

    Returns:
        ``(scores (W, C), block_scores (W, C, n_blocks))``: the latter at the fitted poses,
        per contiguous block of each window's points (``verify.block_scores``).
    """

    def one_window(pose_c, p, o, m):
        q, q_ok = verify.free_samples(p, o, m, n_free, 0.3)

        def terms(y):
            return verify.point_terms(y, p, q, maps.origin, maps.res, maps.sdf4, maps.pen4, sigma)

        def one(y):
            return verify.score_fields(
                y, p, m, q, q_ok, maps.origin, maps.res, maps.sdf4, maps.pen4, sigma, lam
            )

        def blocks(y):
            hit, pen = terms(y)
            return verify.block_scores(hit, pen, m, q_ok, n_blocks, lam)

        y = pose_c  # (C, 3)
        best = jax.vmap(one)(y)
        for st_xy, st_th in steps:
            for axis, st in ((0, st_xy), (1, st_xy), (2, st_th)):
                centre = y
                for sign in (1.0, -1.0):
                    move = jnp.zeros(3, y.dtype).at[axis].set(sign * st)
                    cand = se2.compose(centre, move[None])
                    sc = jax.vmap(one)(cand)
                    better = sc > best
                    best = jnp.where(better, sc, best)
                    y = jnp.where(better[:, None], cand, y)
        return best, jax.vmap(blocks)(y)

    return jax.vmap(one_window)(poses, pts, org, pmask)


def certify(k, t_star, comp, comp_ok, X, evidence, bounds, maps, p, n_slots: int = 12):
    """``CertStats`` of the competitors of ``T*`` at prefix ``k``.

    Args:
        k: ``()`` prefix; t_star: ``(3,)``; comp: ``(C, 3)`` with ``comp_ok (C,)``.
        X: ``(K, 3)`` odometry pose of each window's last scan.
        evidence: ``(points (K, P, 2), origins (K, P, 2), mask (K, P))`` per window, in the
            window's frame.
        bounds: ``(start (K,), end (K,))``; maps: ``DecisionMaps``; p: ``DecisionParams``.
        n_slots: static number of disjoint windows scored.
    """
    pts, org, pmask = evidence
    start, end = bounds
    has = jnp.any(pmask, axis=1) & (jnp.arange(start.shape[0]) <= k)
    idx, ok = chain(k, start, end, has, n_slots)
    Xw = X[idx]  # (W, 3)
    anchors = jnp.concatenate([t_star[None], comp], axis=0)  # (1 + C, 3)
    poses = se2.compose(anchors[None, :, :], Xw[:, None, :])  # (W, 1 + C, 3)
    s, sb = _window_scores(poses, pts[idx], org[idx], pmask[idx], maps, p.cert_sigma, 1.0,
                           FREE_PER_RAY)  # fmt: skip
    adv = s[:, :1] - s[:, 1:]  # (W, C)
    # a block's advantage at equal confidence with a whole window (module docstring)
    scale = math.sqrt(sb.shape[2] * MARGIN_POINTS / pts.shape[1])
    adv_block = jnp.max(sb[:, :1, :] - sb[:, 1:, :], axis=2) / scale  # (W, C)
    contra = jnp.maximum(adv, adv_block)
    max_adv = jnp.max(jnp.where(ok[:, None], contra, -jnp.inf), axis=0)
    min_adv = jnp.min(jnp.where(ok[:, None], adv, jnp.inf), axis=0)
    here = se2.compose(anchors, X[k])
    dxy, dth = se2.distance_pair(here[1:], here[0])
    distinct = (dxy > CORRECT[0]) | (dth > CORRECT[1])
    # without evidence nothing is ruled out: every distinct competitor stays live
    valid = comp_ok & distinct
    return CertStats(comp, valid, max_adv, min_adv, jnp.sum(ok).astype(jnp.int32))


def relation(t_star, c):
    """Kind of competitor ``c`` relative to ``T*``: the motion ``g = C T*^-1`` of the floor
    plan; ``(kind, tau (2,))`` with kind 1 translation (``|yaw| < 5 deg``, tau its
    translation), 3 rotation (a quarter-turn multiple within 5 deg), else 2 multimodal."""
    g = se2.compose(c, se2.inverse(t_star))
    yaw = jnp.abs(se2.wrap(g[2]))
    quarter = jnp.abs(yaw - jnp.round(yaw / (math.pi / 2)) * (math.pi / 2))
    tol = math.radians(5.0)
    kind = jnp.where(yaw < tol, 1, jnp.where(quarter < tol, 3, 2)).astype(jnp.int32)
    return kind, jnp.where(kind == 1, g[:2], jnp.zeros(2, g.dtype))
