"""Policy variants of our layer (traced flags) and the forced-choice baselines.

Variants of our method (``OURS_VARIANTS``) differ only in traced flags, so one compiled
function evaluates all of them:

* ``ours``: gate + independent consensus + lattice + probe + certification (the probe's
  aliases and every other explanation judged by the scans, ``certify``), floors from
  ``DecisionParams``;
* ``paper``: the paper's layer: as ``ours`` without the certification (an alias blocks a
  commit when the gate admits it);
* ``no_probe``: no alias probe and no certification (the lattice test on tied groups stays);
* ``consensus_only``: no gate anywhere; the probe re-gates aliases, so it goes too;
* ``ours_b2_d1``, ``ours_b4_d2``: commit floors ``(b_min, delta_min)`` = (2, 1), (4, 2)
  (``ours`` is (3, 2)).

Baselines (same candidates, same thresholds; ``BASELINES``):

* ``single_shot``: the front-end top-1 of the first window with a candidate, committed there.
* ``support``: head-count over *all* accumulated candidates. A candidate's support is the
  number of accumulated candidates within ``(delta_xy, delta_theta)`` of it; the winner is the
  most supported (ties: higher score), its anchor the mean pose of its neighbourhood, the
  runner-up the most supported candidate outside it. Commits at the first window where
  ``n1 >= support_ratio * n2`` and ``n1 > n2`` (ratio 1.5, set once).
* ``confidence``: per window, the top-1 score ``s1`` over the best score ``s2`` of a candidate
  not within ``delta`` of the top-1; commits at the first window with ``s1 >= 1.2 s2`` (or no
  runner-up), anchor that top-1.
* ``gate_only``: at every prefix, the highest-scoring candidate passing the gate; COMMIT as
  soon as one exists (stateless, like our layer).

The forced-choice baselines (single_shot, support, confidence) are sticky: once triggered at
window ``k0`` they stay COMMIT with the anchor chosen at ``k0``; one that never triggers is
forced to commit at the last valid window (support: its anchor there; confidence: the top-1
of the last window with candidates).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import lattice
from mfcl_jax.decision.state import COMMIT, DEFER, DecisionParams, Decisions

__all__ = ["Variants", "OURS_VARIANTS", "BASELINES", "variants", "baselines"]

# name: (use_gate, use_probe, use_cert, b_min, delta_min); floors < 0: from DecisionParams.
OURS_VARIANTS = {
    "ours": (True, True, True, -1.0, -1.0),
    "paper": (True, True, False, -1.0, -1.0),
    "no_probe": (True, False, False, -1.0, -1.0),
    "consensus_only": (False, False, False, -1.0, -1.0),
    "ours_b2_d1": (True, True, True, 2.0, 1.0),
    "ours_b4_d2": (True, True, True, 4.0, 2.0),
}
BASELINES = ("single_shot", "support", "confidence", "gate_only")


@dataclass(frozen=True)
class Variants:
    """Traced flags of our method's variants, each ``(V,)``."""

    use_gate: jax.Array
    use_probe: jax.Array
    use_cert: jax.Array
    b_min: jax.Array
    delta_min: jax.Array


jax.tree_util.register_dataclass(
    Variants,
    data_fields=["use_gate", "use_probe", "use_cert", "b_min", "delta_min"],
    meta_fields=[],
)


def variants(names=tuple(OURS_VARIANTS)) -> Variants:
    """``Variants`` for the named entries of ``OURS_VARIANTS``."""
    bad = [n for n in names if n not in OURS_VARIANTS]
    if bad:
        raise ValueError(f"variants: unknown names {bad}; known {list(OURS_VARIANTS)}")
    cols = list(zip(*(OURS_VARIANTS[n] for n in names), strict=True))
    return Variants(
        use_gate=jnp.asarray(cols[0], bool),
        use_probe=jnp.asarray(cols[1], bool),
        use_cert=jnp.asarray(cols[2], bool),
        b_min=jnp.asarray(cols[3], jnp.float32),
        delta_min=jnp.asarray(cols[4], jnp.float32),
    )


def _decision(state, anchor, reason, max_score, b1=0, b2=0, n=0, c=0.0, gate=False):
    i32 = jnp.int32
    z = jnp.zeros_like(max_score)
    return Decisions(
        state=state.astype(i32),
        kind=jnp.full_like(state, lattice.KIND_NONE, dtype=i32),
        anchor=anchor,
        tau=jnp.zeros((*state.shape, 2), anchor.dtype),
        b1=jnp.asarray(b1, i32) + jnp.zeros_like(state, i32),
        b2=jnp.asarray(b2, i32) + jnp.zeros_like(state, i32),
        margin=(jnp.asarray(b1, i32) - jnp.asarray(b2, i32)) + jnp.zeros_like(state, i32),
        n_groups=jnp.zeros_like(state, i32),
        n_champions=jnp.asarray(n, i32) + jnp.zeros_like(state, i32),
        spread=z,
        rooms=jnp.zeros_like(state, i32),
        c_winner=jnp.asarray(c, jnp.float32) + z,
        winner_gate=jnp.asarray(gate, bool) | jnp.zeros_like(state, bool),
        probe_alias=jnp.zeros_like(state, bool),
        probe_c=z,
        reason=reason.astype(i32),
        max_score=max_score,
        alias_motion=jnp.zeros((*state.shape, 3), anchor.dtype),
        competitor=jnp.zeros((*state.shape, 3), anchor.dtype),
        has_competitor=jnp.zeros_like(state, bool),
        n_live=jnp.zeros_like(state, i32),
    )


def _sticky(trigger, anchor, avail):
    """First trigger (else the last window in ``avail``) -> per-window state, anchor, reason."""
    kk = trigger.shape[0]
    idx = jnp.arange(kk)
    fired = trigger & avail
    last = jnp.max(jnp.where(avail, idx, -1))
    k0 = jnp.where(jnp.any(fired), jnp.argmax(fired), last)
    ok = (k0 >= 0) & (idx >= k0)
    state = jnp.where(ok, COMMIT, DEFER)
    reason = jnp.where(ok, 0, 8)
    a = anchor[jnp.maximum(k0, 0)]
    return state, jnp.broadcast_to(a, anchor.shape), reason


def _within(a, b, p):
    """Both tolerances, without atan2: ``|dxy| <= delta_xy`` and ``cos(dtheta) >= cos(delta)``."""
    d = a[..., :2] - b[..., :2]
    near = jnp.sum(d * d, axis=-1) <= p.delta_xy * p.delta_xy
    cosd = jnp.cos(a[..., 2]) * jnp.cos(b[..., 2]) + jnp.sin(a[..., 2]) * jnp.sin(b[..., 2])
    return near & (cosd >= jnp.cos(p.delta_theta))


def _within_pairs(h, p):
    """``_within`` of every pair of ``h (M, 3)`` -> ``(M, M)``, trig once per pose."""
    c, sn = jnp.cos(h[:, 2]), jnp.sin(h[:, 2])
    d = h[:, None, :2] - h[None, :, :2]
    near = jnp.sum(d * d, axis=-1) <= p.delta_xy * p.delta_xy
    cosd = c[:, None] * c[None, :] + sn[:, None] * sn[None, :]
    return near & (cosd >= jnp.cos(p.delta_theta))


def baselines(H, score, mask, cons, wmask, p: DecisionParams) -> Decisions:
    """All baselines of one run at every prefix.

    Args:
        H: ``(K, J, 3)``; score, mask: ``(K, J)``; cons: ``(K, J, K)`` gate table;
        wmask: ``(K,)`` valid windows; p: scalar ``DecisionParams``.

    Returns:
        ``Decisions`` with leading shape ``(K, len(BASELINES))``.
    """
    kk, jj = score.shape
    idx = jnp.arange(kk)
    ok = mask & (score >= p.score_floor) & wmask[:, None]
    s = jnp.where(ok, score, -jnp.inf)
    has = jnp.any(ok, axis=1)
    top = jnp.argmax(s, axis=1)
    top_pose = H[idx, top]  # (K, 3)
    s1 = s[idx, top]
    cum_max = jax.lax.cummax(jnp.where(mask, score, -jnp.inf).max(axis=1))
    max_score = jnp.where(jnp.isfinite(cum_max), cum_max, 0.0)

    # single shot
    st, an, rs = _sticky(has, top_pose, has)
    single = _decision(st, an, rs, max_score, n=1)

    # confidence
    far = ~_within(H, top_pose[:, None, :], p) & ok
    s2 = jnp.max(jnp.where(far, score, -jnp.inf), axis=1)
    trig = has & ((s1 >= p.confidence_ratio * s2) | ~jnp.isfinite(s2))
    st, an, rs = _sticky(trig, top_pose, has)
    conf = _decision(st, an, rs, max_score, n=1)

    # support: neighbour counts per window, accumulated over windows. The pairwise matrix is
    # built once (per threshold set); heading trig is taken per candidate, not per pair.
    flat_h, flat_ok = H.reshape(-1, 3), ok.reshape(-1)
    flat_w = jnp.repeat(idx, jj)
    nb = _within_pairs(flat_h, p) & flat_ok[None, :]  # (KJ, KJ)
    per_w = jnp.sum(nb.reshape(kk * jj, kk, jj), axis=-1, dtype=jnp.int32)  # (KJ, K)
    support = jnp.cumsum(per_w, axis=1)  # support of a at prefix k
    flat_s = score.reshape(-1)

    def at_prefix(k):
        elig = flat_ok & (flat_w <= k)
        cnt = jnp.where(elig, support[:, k], -1)
        key = jnp.where(elig, flat_s, -jnp.inf)
        # most supported, ties to the higher score, then the lower index
        a = jnp.argmax(jnp.where(cnt == jnp.max(cnt), key, -jnp.inf))
        a = jnp.where(jnp.any(elig), a, 0)
        n1 = jnp.maximum(cnt[a], 0)
        members = nb[a] & (flat_w <= k)
        n2 = jnp.maximum(jnp.max(jnp.where(~members & elig, cnt, 0)), 0)
        anchor = se2.mean_pose(flat_h, members.astype(flat_h.dtype))
        lead = n1.astype(jnp.float32) >= p.support_ratio * n2.astype(jnp.float32)
        trig = jnp.any(elig) & lead & (n1 > n2)
        return trig, anchor, n1, n2

    trig, anchor, n1, n2 = jax.vmap(at_prefix)(idx)
    seen = (jax.lax.cummax(has.astype(jnp.int32)) > 0) & wmask
    st, an, rs = _sticky(trig, anchor, seen)
    k_pick = jnp.clip(jnp.argmax(st == COMMIT), 0, kk - 1)
    sup = _decision(st, an, rs, max_score, b1=n1[k_pick], b2=n2[k_pick])

    # gate only (stateless)
    visible = ok[None, :, :] & (idx[None, :] <= idx[:, None])[:, :, None]  # (Kp, K, J)
    feas = visible & (jnp.moveaxis(cons, -1, 0) >= p.tau_c)
    gs = jnp.where(feas, score[None], -jnp.inf).reshape(kk, -1)
    best = jnp.argmax(gs, axis=1)
    any_f = jnp.any(feas.reshape(kk, -1), axis=1)
    g_anchor = flat_h[best]
    any_v = jnp.any(visible.reshape(kk, -1), axis=1)
    g_reason = jnp.where(any_f, 0, jnp.where(any_v, 3, 1))
    g_state = jnp.where(any_f, COMMIT, DEFER)
    gate_c = jnp.moveaxis(cons, -1, 0).reshape(kk, -1)[idx, best]
    gonly = _decision(g_state, g_anchor, g_reason, max_score, n=1, c=gate_c, gate=any_f)

    return jax.tree.map(lambda *x: jnp.stack(x, axis=1), single, sup, conf, gonly)
