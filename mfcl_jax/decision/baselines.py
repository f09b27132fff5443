"""The forced-choice baselines, one window at a time (same candidates, same thresholds).

* ``single_shot``: the front-end top-1 of the first window with a candidate, committed there.
* ``support``: head-count over *all* accumulated candidates. A candidate's support is the
  number of accumulated candidates within ``(delta_xy, delta_theta)`` of it; the winner is the
  most supported (ties: higher score), its anchor the mean pose of its neighbourhood, the
  runner-up the most supported candidate outside it. Commits at the first window where
  ``n1 >= support_ratio * n2`` and ``n1 > n2`` (ratio 1.5, set once).
* ``confidence``: per window, the top-1 score ``s1`` over the best score ``s2`` of a candidate
  not within ``delta`` of the top-1; commits at the first window with ``s1 >= 1.2 s2`` (or no
  runner-up), anchor that top-1.
* ``gate_only``: at every window, the highest-scoring candidate passing the gate; COMMIT as
  soon as one exists (stateless, like our layer).

The forced-choice baselines (single_shot, support, confidence) are sticky: once triggered
they stay COMMIT with the anchor chosen then; one that never triggers is forced to commit at
the run's last window (``WindowEvidence.last``; support: its anchor there; confidence and
single-shot: the top-1 of the last window with candidates). Before a commit the reported
anchor is this window's pick and ``B1``/``B2`` (support) this window's head-counts.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import lattice
from mfcl_jax.decision.outcome import COMMIT, DEFER, Decision

__all__ = ["Sticky", "BaselineState", "start", "step", "within"]


@dataclass(frozen=True)
class Sticky:
    """A forced-choice commit: whether it fired, its anchor and head-counts (per set)."""

    fired: jax.Array  # (S,) bool
    anchor: jax.Array  # (S, 3)
    counts: jax.Array  # (S, 2) int32 B1, B2 at the commit (support)


@dataclass(frozen=True)
class BaselineState:
    single: Sticky
    support: Sticky
    confidence: Sticky
    any_has: jax.Array  # () bool: some window had a candidate
    last_top: jax.Array  # (3,) top-1 of the last window with candidates
    max_score: jax.Array  # () running maximum of the candidates' scores


for _cls in (Sticky, BaselineState):
    jax.tree_util.register_dataclass(
        _cls, data_fields=list(_cls.__dataclass_fields__), meta_fields=[]
    )


def start(n_sets: int) -> BaselineState:
    def sticky():
        return Sticky(jnp.zeros(n_sets, bool), jnp.zeros((n_sets, 3)),
                      jnp.zeros((n_sets, 2), jnp.int32))  # fmt: skip

    return BaselineState(sticky(), sticky(), sticky(), jnp.bool_(False), jnp.zeros(3),
                         jnp.float32(-jnp.inf))  # fmt: skip


def within(a, b, p):
    """Both tolerances, without atan2: ``|dxy| <= delta_xy`` and ``cos(dtheta) >= cos(delta)``."""
    d = a[..., :2] - b[..., :2]
    near = jnp.sum(d * d, axis=-1) <= p.delta_xy * p.delta_xy
    cosd = jnp.cos(a[..., 2]) * jnp.cos(b[..., 2]) + jnp.sin(a[..., 2]) * jnp.sin(b[..., 2])
    return near & (cosd >= jnp.cos(p.delta_theta))


def _decision(state, anchor, reason, max_score, b1=0, b2=0, n=0, c=0.0, gate=False):
    i32 = jnp.int32
    shape = jnp.shape(state)
    zi = jnp.zeros(shape, i32)
    zf = jnp.zeros(shape, jnp.float32)
    return Decision(
        state=jnp.asarray(state, i32) + zi,
        kind=zi + lattice.KIND_NONE,
        anchor=jnp.broadcast_to(anchor, (*shape, 3)).astype(jnp.float32),
        tau=jnp.zeros((*shape, 2), jnp.float32),
        b1=jnp.asarray(b1, i32) + zi,
        b2=jnp.asarray(b2, i32) + zi,
        margin=jnp.asarray(b1, i32) - jnp.asarray(b2, i32) + zi,
        n_groups=zi,
        n_champions=zi + n,
        spread=zf,
        rooms=zi,
        c_winner=zf + c,
        winner_gate=jnp.zeros(shape, bool) | gate,
        probe_alias=jnp.zeros(shape, bool),
        probe_c=zf,
        reason=jnp.asarray(reason, i32) + zi,
        max_score=zf + max_score,
        alias_motion=jnp.zeros((*shape, 3), jnp.float32),
        competitor=jnp.zeros((*shape, 3), jnp.float32),
        has_competitor=jnp.zeros(shape, bool),
        n_live=zi,
        certified=jnp.zeros(shape, bool),
        searched=jnp.zeros(shape, bool),
        n_rejected=zi,
        dropped=zi,
        llr=zf + jnp.nan,
        test_anchor=jnp.zeros((*shape, 3), jnp.float32),
    )


def _fire(st: Sticky, trig, avail, last, anchor, counts) -> Sticky:
    """Fires where ``trig`` (and available), or at the last window where never fired."""
    now = ~st.fired & avail & (trig | last)
    return Sticky(
        st.fired | now,
        jnp.where(now[:, None], anchor, st.anchor),
        jnp.where(now[:, None], counts, st.counts),
    )


def _report(st: Sticky, pick, max_score, counts=None):
    state = jnp.where(st.fired, COMMIT, DEFER)
    reason = jnp.where(st.fired, 0, 8)
    anchor = jnp.where(st.fired[:, None], st.anchor, pick)
    c = st.counts if counts is None else jnp.where(st.fired[:, None], st.counts, counts)
    return _decision(state, anchor, reason, max_score, c[:, 0], c[:, 1], n=1)


def step(bs: BaselineState, H, score, mask, cons, support, k, last, p, conf_ratio,
         sup_ratio) -> tuple[BaselineState, jax.Array, Decision]:  # fmt: skip
    """One window of every baseline and threshold set.

    Args:
        H: ``(C, J, 3)`` the history's anchors, the new window at row ``k``; score, mask,
            cons: ``(C, J)`` (mask false on empty rows); support: ``(C, J)`` int32 head-counts
            before this window.
        last: ``()`` bool: the run's last window.
        p: scalar ``DecisionParams``; conf_ratio, sup_ratio: ``(S,)`` the sets' knobs.

    Returns:
        ``(state, support (C, J), Decision (S, 4))`` in ``lanes.BASELINES`` order.
    """
    n_sets = conf_ratio.shape[0]
    kk, jj = score.shape
    ok = mask & (score >= p.score_floor)
    ok_new = ok[k]
    s_new = jnp.where(ok_new, score[k], -jnp.inf)
    has = jnp.any(ok_new)
    top = jnp.argmax(s_new)
    top_pose, s1 = H[k, top], s_new[top]
    new_max = jnp.max(jnp.where(mask[k], score[k], -jnp.inf))
    max_run = jnp.maximum(bs.max_score, new_max)
    max_score = jnp.where(jnp.isfinite(max_run), max_run, 0.0)
    any_has = bs.any_has | has
    last_top = jnp.where(has, top_pose, bs.last_top)
    trig_all = jnp.ones(n_sets, bool)
    last_s = jnp.broadcast_to(last, (n_sets,))
    zero2 = jnp.zeros((n_sets, 2), jnp.int32)

    single = _fire(bs.single, trig_all & has, jnp.broadcast_to(any_has, (n_sets,)), last_s,
                   jnp.where(has, top_pose, last_top), zero2)  # fmt: skip

    far = ~within(H[k], top_pose, p) & ok_new
    s2 = jnp.max(jnp.where(far, score[k], -jnp.inf))
    trig = has & ((s1 >= conf_ratio * s2) | ~jnp.isfinite(s2))
    conf = _fire(bs.confidence, trig, jnp.broadcast_to(any_has, (n_sets,)), last_s, last_top,
                 zero2)  # fmt: skip

    # support: head-counts of every candidate over every window so far
    flat_h, flat_ok, flat_s = H.reshape(-1, 3), ok.reshape(-1), score.reshape(-1)
    near_new = within(flat_h[:, None, :], H[k][None, :, :], p)  # (CJ, J)
    add_old = jnp.sum(near_new & ok_new[None, :], axis=1, dtype=jnp.int32)
    count_new = jnp.sum(near_new & flat_ok[:, None], axis=0, dtype=jnp.int32)
    row = jnp.repeat(jnp.arange(kk), jj)
    flat_sup = jnp.where(row == k, jnp.tile(count_new, kk), support.reshape(-1) + add_old)
    cnt = jnp.where(flat_ok, flat_sup, -1)
    a = jnp.argmax(jnp.where(cnt == jnp.max(cnt), flat_s, -jnp.inf))
    a = jnp.where(jnp.any(flat_ok), a, 0)
    n1 = jnp.maximum(cnt[a], 0)
    members = within(flat_h, flat_h[a], p) & flat_ok
    n2 = jnp.maximum(jnp.max(jnp.where(~members & flat_ok, cnt, 0)), 0)
    anchor = se2.mean_pose(flat_h, members.astype(flat_h.dtype))
    lead = n1.astype(jnp.float32) >= sup_ratio * n2.astype(jnp.float32)
    trig = jnp.any(flat_ok) & lead & (n1 > n2)
    counts = jnp.broadcast_to(jnp.stack([n1, n2]).astype(jnp.int32), (n_sets, 2))
    sup = _fire(bs.support, trig, jnp.broadcast_to(any_has, (n_sets,)), last_s, anchor, counts)

    # gate only (stateless)
    feas = flat_ok & (cons.reshape(-1) >= p.tau_c)
    best = jnp.argmax(jnp.where(feas, flat_s, -jnp.inf))
    any_f = jnp.any(feas)
    g_reason = jnp.where(any_f, 0, jnp.where(jnp.any(flat_ok), 3, 1))
    gonly = _decision(jnp.where(any_f, COMMIT, DEFER), flat_h[best], g_reason, max_score, n=1,
                      c=cons.reshape(-1)[best], gate=any_f)  # fmt: skip
    gonly = jax.tree.map(lambda x: jnp.broadcast_to(x, (n_sets, *x.shape)), gonly)

    out = [
        _report(single, top_pose, max_score),
        _report(sup, anchor, max_score, counts),
        _report(conf, top_pose, max_score),
        gonly,
    ]
    dec = jax.tree.map(lambda *x: jnp.stack(x, axis=1), *out)  # (S, 4)
    new = BaselineState(single, sup, conf, any_has, last_top, max_run)
    return new, flat_sup.reshape(kk, jj), dec
