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

Fair comparison: every explanation (``T*`` included) is scored in every window at its best
fit within a few centimetres and tenths of a degree, with free-space samples along each ray
(``fitted``).

Per competitor the advantage ``adv_w = s_w(T*) - s_w(C)`` gives two numbers, the largest and
the smallest advantage over the windows; ``finish`` compares them with the margin
``cert_margin`` (a knob): ``C`` is ruled out when some window contradicts it
(``max adv >= margin``) and none favours it (``min adv > -margin``); ``T*`` is dominated when
some competitor is favoured somewhere and contradicted nowhere. Otherwise ``C`` stays a live
explanation and the decision is AMBIGUOUS with ``C``'s kind (relative to ``T*``: a translation
with its period, a rotation, or multimodal; a mirrored wing shows up as one of these, since a
reflection is not a rigid motion).

Turned competitors (``turned``). A building with a rotational self-motion ``g`` (two units
that are half-turn images of each other) is told apart from ``g T*`` only where its plan
breaks the symmetry: a stub, a door, one wall. The two terms of the score weigh that
differently. Rays that cross a plan wall under ``C`` (the free-space term) say that the plan
and the scans cannot both be right there under ``C``; points that ``T*`` puts on a plan wall
and ``C`` puts in free space (the occupancy term) say only that ``C`` leaves them unexplained,
which a wall piece the plan does not show explains as well. Where the plan is wrong at the
very feature that breaks the symmetry (a stub built where the plan has none, and none where
it has one: the benchmark's ``near_symmetric`` axis, ``stub_twin``), the occupancy term
favours the wrong half by what it favours the right half by when the plan is right, and no
margin tells the two apart. So a competitor turned from ``T*`` by a quarter-turn multiple
(``relation`` kind rotation: the probe's rotated aliases, and any group, runner-up or rival
so placed, since the room-based ``symmetry`` misses the half turn of a building of
rectangles) is ruled out by the free-space term (the window's or a block's, at the usual
scales), or by the whole score only where two blocks of one window contradict it: one local
feature does not rule a turned placement out, walls that differ around the robot do.
The probe's period-shifted aliases are images of ``T*`` under a self-motion too (a row of
bays shifted by its pitch: the same trap along a translation, a stub seen one bay over) and
are held to the same rule (``self_images``). Other translated competitors (another group, a
window's runner-up, a rival of the path) keep every block: offices whose walls differ from a
shifted copy at one doorway are told apart by one block. What this costs and what the
alternatives did is measured in ``docs/benchmark.md``.

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
from mfcl_jax.decision import lattice
from mfcl_jax.decision.fitted import FREE_PER_RAY, window_scores

__all__ = [
    "CertStats",
    "chain",
    "competitors",
    "certify",
    "relation",
    "self_images",
    "CERT_BLOCKS",
    "CORRECT",
    "MARGIN_POINTS",
]

CORRECT = (1.0, math.radians(5.0))  # same answer: the robot placed within 1 m and 5 deg
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
    ran: jax.Array  # () bool: computed (False: skipped, nothing certified)


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


CHUNK = 16  # competitors scored together in one window


def certify(k, t_star, comp, comp_ok, X, evidence, bounds, maps, p, n_slots: int = 12,
            turned=None):  # fmt: skip
    """``CertStats`` of the competitors of ``T*`` at the newest window ``k``.

    Only what counts is scored: the windows of the scan-disjoint chain (at most ``n_slots``)
    and the competitors with ``comp_ok``, in chunks of ``CHUNK`` (loops whose trip counts are
    the chain's length and the competitors' number: the certification runs unbatched, inside
    ``sparse_cond``, so it pays for what the window has, not for its capacities).

    Args:
        k: ``()`` newest row; t_star: ``(3,)``; comp: ``(C, 3)`` with ``comp_ok (C,)``.
        X: ``(K, 3)`` odometry pose of each window's last scan.
        evidence: ``(points (K, P, 2), origins (K, P, 2), mask (K, P))`` per window, in the
            window's frame.
        bounds: ``(start (K,), end (K,))``; maps: ``DecisionMaps``; p: ``DecisionParams``.
        n_slots: static number of disjoint windows scored at most.
        turned: ``(C,)`` bool, the competitors turned from ``T*`` by a quarter-turn
            multiple, contradicted only by the free-space term or by two blocks of a window
            (module docstring), or None (none).
    """
    pts, org, pmask = evidence
    turned = jnp.zeros(comp.shape[0], bool) if turned is None else turned
    start, end = bounds
    has = jnp.any(pmask, axis=1) & (jnp.arange(start.shape[0]) <= k)
    idx, ok = chain(k, start, end, has, n_slots)  # the chain first
    n_win = jnp.sum(ok)
    n_c = comp.shape[0]
    n_pad = -(-n_c // CHUNK) * CHUNK
    order = jnp.argsort(~comp_ok, stable=True)  # competitors that count first
    order = jnp.concatenate([order, jnp.full(n_pad - n_c, order[0])])
    turned = turned[order]
    n_chunks = (jnp.sum(comp_ok) + CHUNK - 1) // CHUNK
    # a block's advantage at equal confidence with a whole window (module docstring)
    scale = math.sqrt(CERT_BLOCKS * MARGIN_POINTS / pts.shape[1])

    def scores(w, anchors):
        poses = se2.compose(anchors, X[w][None])[None]  # (1, n, 3)
        out = window_scores(poses, pts[w][None], org[w][None], pmask[w][None], maps,
                            p.cert_sigma, 1.0, FREE_PER_RAY, n_blocks=CERT_BLOCKS)  # fmt: skip
        return tuple(a[0] for a in out)

    def window(i, acc):
        w = idx[i]
        s_t, sb_t, f_t, fb_t = scores(w, t_star[None])

        def chunk(j, acc):
            hi, lo = acc
            sel = jax.lax.dynamic_slice(order, (j * CHUNK,), (CHUNK,))
            s, sb, f, fb = scores(w, comp[sel])
            adv = s_t[0] - s
            contra = jnp.maximum(adv, jnp.max(sb_t[:1] - sb, axis=1) / scale)
            # a turned competitor: the free-space term, or the whole score where two blocks
            # of the window contradict it (not one local feature)
            second = jnp.sort(sb_t[:1] - sb, axis=1)[:, -2] / scale
            contra_free = jnp.maximum(f_t[0] - f, jnp.max(fb_t[:1] - fb, axis=1) / scale)
            only = jax.lax.dynamic_slice(turned, (j * CHUNK,), (CHUNK,))
            contra = jnp.where(only, jnp.maximum(contra_free, second), contra)
            at = (j * CHUNK,)
            hi = jax.lax.dynamic_update_slice(
                hi, jnp.maximum(jax.lax.dynamic_slice(hi, at, (CHUNK,)), contra), at
            )
            lo = jax.lax.dynamic_update_slice(
                lo, jnp.minimum(jax.lax.dynamic_slice(lo, at, (CHUNK,)), adv), at
            )
            return hi, lo

        return jax.lax.fori_loop(0, n_chunks, chunk, acc)

    acc = (jnp.full(n_pad, -jnp.inf), jnp.full(n_pad, jnp.inf))
    hi, lo = jax.lax.fori_loop(0, n_win, window, acc)
    max_adv = jnp.full(n_c, -jnp.inf).at[order[:n_c]].set(hi[:n_c])
    min_adv = jnp.full(n_c, jnp.inf).at[order[:n_c]].set(lo[:n_c])
    anchors = jnp.concatenate([t_star[None], comp], axis=0)
    here = se2.compose(anchors, X[k])
    dxy, dth = se2.distance_pair(here[1:], here[0])
    distinct = (dxy > CORRECT[0]) | (dth > CORRECT[1])
    # without evidence nothing is ruled out: every distinct competitor stays live
    valid = comp_ok & distinct
    return CertStats(comp, valid, max_adv, min_adv, n_win.astype(jnp.int32), jnp.bool_(True))


def self_images(t_star, comp, n_aliases: int):
    """``(C,)`` bool: the competitors ``comp (C, 3)`` that are images of ``T*`` under a
    self-motion of the building, told apart from it only where the plan breaks the symmetry:
    those turned from ``T*`` by a quarter-turn multiple (``relation`` kind rotation, whatever
    found them) and the probe's period-shifted aliases (the first ``n_aliases`` rows, kind
    translation). ``certify`` rules them out by the free-space term or by two blocks of a
    window only (``turned``; module docstring)."""
    kind = jax.vmap(lambda a: relation(t_star, a)[0])(comp)
    alias = jnp.arange(comp.shape[0]) < n_aliases
    return (kind == lattice.ROTATION) | (alias & (kind == lattice.TRANSLATION))


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
