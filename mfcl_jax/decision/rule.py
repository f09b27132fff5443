"""The selective rule at the newest window (Algorithm 1), on the layer's buffers.

``core`` summarises the windows in the layer's history at the newest window ``k`` (champions,
consensus groups, the lattice over all groups, the alias probe); ``certify_core`` re-scores
the history's scan-disjoint windows under ``T*`` and every competing explanation; ``finish``
applies one lane's flags and floors. Order of tests (first that fires wins):

1. no valid candidate                                  -> DEFER ("no anchors")
2. best score below the floor                          -> DEFER ("below floor")
3. no admitted champion (all gated)                    -> DEFER ("no feasible champion")
4. fewer than ``b_min`` scan-disjoint windows have a champion (any group): the evidence is
   not saturated yet; no room labels needed, so occupancy maps work -> DEFER ("unsaturated")
5. T* fails the gate / spread > sigma_max              -> DEFER ("winner infeasible"/"spread")
6. margin < delta_min and tied groups form a lattice   -> AMBIGUOUS(translation, tau)
7. B1 >= b_min and margin >= delta_min: without the certification the probe decides (an
   admissible translational alias -> AMBIGUOUS(translation, tau), a rotational one
   ``g T*`` -> AMBIGUOUS(rotation)); with it, a competitor the scans do not rule out ->
   AMBIGUOUS with the competitor's kind, ``T*`` favoured against nowhere -> COMMIT(T*)
8. otherwise -> AMBIGUOUS (multimodal with >= 2 groups, no kind with one group)

The certification (``certify``) runs only where it can change what a lane reports: where
tests 1-5 pass, the winner's support reaches the lane's ``b_min`` and the lane is not holding
a commit that ``T*`` confirms (``needs_certificate``). Where it ran, the runner-up support
``B2`` counts only the groups whose anchors the scans have not ruled out; elsewhere it counts
every group, as in the paper (``Decision.certified`` says which).

``T*`` (``Decision.anchor``) is the mean of the winner's most recent champions
(``DecisionParams.recent``); tests 5 and 7 use it because it is the anchor a commit hands over.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import certify, consensus, lattice, probe
from mfcl_jax.decision.outcome import AMBIGUOUS, COMMIT, DEFER, Decision

__all__ = ["Core", "core", "certify_core", "skipped", "needs_certificate", "finish"]


@dataclass(frozen=True)
class Core:
    """What a decision at the newest window needs before a lane's floors and flags apply."""

    any_anchor: jax.Array  # () bool
    max_score: jax.Array  # ()
    n_champions: jax.Array  # () int32
    groups: consensus.Groups
    fit: lattice.LatticeFit  # residual tests of the group anchors (shared by every mask)
    all_ok: jax.Array  # () bool lattice over every live group
    all_tau: jax.Array  # (2,)
    probe_result: probe.ProbeResult  # every probe period on (a lane may switch it off)
    admitted: jax.Array  # (C, J) bool candidates past the floor (and the gate)


jax.tree_util.register_dataclass(Core, data_fields=list(Core.__dataclass_fields__), meta_fields=[])


def core(k, H, score, mask, cons, s_end, start, end, traj, traj_valid, maps, sym, p, use_gate,
         n_cap: int = 3) -> Core:  # fmt: skip
    """Champions, groups, the all-group lattice and the probe at the newest window.

    Args:
        k: ``()`` int32 row of the newest window in the history (rows ``0..k`` are visible).
        H: ``(C, J, 3)`` candidate anchors; score, mask: ``(C, J)``.
        cons: ``(C, J)`` gate consistency of each candidate over the trajectory so far.
        s_end: ``(C,)`` odometric distance travelled at each window's end.
        start, end: ``(C,)`` keyframe bounds of the windows (any common origin).
        traj: ``(T, 3)`` trajectory; traj_valid: ``(T,)`` its samples up to the newest window.
        maps: ``DecisionMaps``; sym: the ``Symmetry`` set used; p: scalar ``DecisionParams``.
        use_gate: ``()`` bool.
        n_cap: static probe shift capacity.
    """
    kk = H.shape[0]
    visible = mask & (jnp.arange(kk) <= k)[:, None]
    any_anchor = jnp.any(visible)
    max_score = jnp.where(any_anchor, jnp.max(jnp.where(visible, score, -jnp.inf)), 0.0)
    admitted = visible & (score >= p.score_floor) & ((cons >= p.tau_c) | ~use_gate)
    ch = consensus.champions(H, score, admitted)
    g = consensus.group(
        ch, p.delta_xy, p.delta_theta, p.recent, start, end, s_end, (p.drift_xy, p.drift_theta)
    )
    live = jnp.arange(kk) < g.n_groups
    fit = lattice.prepare(g.anchor, g.winner, sym.offsets, p.eps_t)
    all_ok, all_tau = lattice.detect_from(
        fit, live, g.winner, sym.offsets, sym.offsets_mask, p.eps_t, p.eps_theta
    )
    taus = jnp.concatenate([all_tau[None], sym.generators.astype(all_tau.dtype)], axis=0)
    taus_mask = jnp.concatenate([all_ok[None], sym.generators_mask])
    # The reported (recency) anchor is the one committed, so it is the one gated and probed.
    pr = probe.probe(
        maps, sym, g.t_star, taus, taus_mask, traj, traj_valid, p.tau_c, p.gamma, p.n_max, n_cap
    )
    n_ch = jnp.sum(ch.has).astype(jnp.int32)
    return Core(any_anchor, max_score, n_ch, g, fit, all_ok, all_tau, pr, admitted)


def certify_core(k, c: Core, H, score, X, evidence, bounds, maps, p, rivals, rivals_ok,
                 n_slots: int = 12) -> certify.CertStats:  # fmt: skip
    """``certify.CertStats`` of the competitors of ``c``'s ``T*``: the probe's aliases, the
    other groups, each window's runner-up and the global search's rivals ``(E, 3)``."""
    g = c.groups
    kk = g.size.shape[0]
    others = (jnp.arange(kk) < g.n_groups) & (jnp.arange(kk) != g.winner)
    pr = c.probe_result
    comp, ok = certify.competitors(
        g.t_star, pr.aliases, pr.aliases_ok, g.anchor, others, H, score, c.admitted, X[k],
        rivals, rivals_ok,
    )  # fmt: skip
    # an image of T* under a self-motion of the building is ruled out by the free-space term
    # or by two blocks of a window (``certify`` module docstring)
    turned = certify.self_images(g.t_star, comp, pr.aliases.shape[0])
    return certify.certify(k, g.t_star, comp, ok, X, evidence, bounds, maps, p, n_slots,
                           turned)  # fmt: skip


def skipped(stats: certify.CertStats) -> certify.CertStats:
    """A ``CertStats`` shaped like ``stats`` that certifies nothing (``ran`` false)."""
    z = jax.tree.map(jnp.zeros_like, stats)
    return certify.CertStats(z.anchor, z.valid, z.max_adv, z.min_adv, z.n_windows, z.ran)


def _saturated(c: Core, p, use_gate, b_min):
    """Tests 1-5 pass: the decision is about the winner's support, not a DEFER."""
    g = c.groups
    gate_w = (c.probe_result.c_winner >= p.tau_c) | ~use_gate
    return (
        c.any_anchor
        & (c.max_score >= p.score_floor)
        & (g.n_groups > 0)
        & (g.seen.astype(jnp.float32) >= b_min)
        & gate_w
        & (g.spread <= p.sigma_max)
    )


def needs_certificate(c: Core, p, use_gate, use_cert, b_min, held) -> jax.Array:
    """Whether the certification can change what a lane reports at this window: tests 1-5
    pass, the winner's support reaches ``b_min``, and the lane does not hold a commit that
    ``T*`` confirms (a held commit ignores the rule's state unless ``T*`` moved away from it;
    ``machine.step``)."""
    g = c.groups
    dxy, dth = se2.distance_pair(g.t_star, held.anchor)
    confirms = held.committed & (dxy <= p.delta_xy) & (dth <= p.delta_theta)
    b1 = g.b1.astype(jnp.float32)
    return use_cert & _saturated(c, p, use_gate, b_min) & (b1 >= b_min) & ~confirms


def finish(c: Core, cert: certify.CertStats, sym, p, use_gate, use_probe, use_cert, b_min,
           delta_min, margin) -> Decision:  # fmt: skip
    """Applies a lane (gate, probe and certification flags, commit floors, the certification
    margin) to a ``Core`` and its ``CertStats``; ``use_gate`` must be the flag ``c`` was
    computed with. Without a certificate (``cert.ran`` false) the lane decides as the
    uncertified layer, which ``needs_certificate`` guarantees cannot reach a commit."""
    g = c.groups
    kk = g.size.shape[0]
    live = jnp.arange(kk) < g.n_groups
    uc = use_cert & cert.ran
    against = cert.max_adv >= margin
    favoured = cert.min_adv <= -margin
    live_c = cert.valid & ~(against & ~favoured) & uc
    # Under the certification a runner-up group counts against the winner only while the
    # scans have not ruled its anchor out. ``certify.competitors`` lists the probe's aliases,
    # the groups' anchors, the runner-ups and the rivals, in that order: slots A .. A + C.
    n_a = c.probe_result.aliases.shape[0]
    rival_group = live & (jnp.arange(kk) != g.winner)
    counted = rival_group & (live_c[n_a : n_a + kk] | ~uc)
    b2 = jnp.max(jnp.where(counted, g.indep, 0)).astype(g.b2.dtype)
    runner_up = jnp.argmax(jnp.where(counted, g.indep, -1))  # the group B2 counts
    tied = (counted | (jnp.arange(kk) == g.winner)) & live
    tied = tied & ((g.b1 - g.indep).astype(jnp.float32) < delta_min)
    lat_ok, lat_tau = lattice.detect_from(
        c.fit, tied, g.winner, sym.offsets, sym.offsets_mask, p.eps_t, p.eps_theta
    )
    pr = c.probe_result
    # probe off == every probe period masked: no alias, zero period and alias consistency
    p_alias = pr.alias & use_probe
    p_tau = jnp.where(use_probe, pr.tau, jnp.zeros_like(pr.tau))
    p_c = jnp.where(use_probe, pr.c_alias, jnp.zeros_like(pr.c_alias))
    r_alias = pr.rot_alias & use_probe
    r_c = jnp.where(use_probe, pr.c_rot, jnp.zeros_like(pr.c_rot))
    gate_w = (pr.c_winner >= p.tau_c) | ~use_gate
    b1, m = g.b1.astype(jnp.float32), (g.b1 - b2).astype(jnp.float32)
    decisive = (b1 >= b_min) & (m >= delta_min)
    # certification: a competitor is ruled out when some window contradicts it and none
    # favours it; T* is dominated when a competitor is favoured somewhere, contradicted nowhere
    dominated = jnp.any(cert.valid & favoured & ~against) & uc
    strongest = jnp.argmin(jnp.where(live_c, cert.max_adv, jnp.inf))
    rival = cert.anchor[strongest]
    c_kind, c_tau = certify.relation(g.t_star, rival)
    blocked = jnp.any(live_c) | dominated
    # without the certification the paper's probe decides alone (gate-admissible aliases);
    # a certifying lane without a certificate cannot commit (``needs_certificate``)
    gate_alias = p_alias | r_alias  # reported either way (diagnostic)
    p_alias = p_alias & ~use_cert
    r_alias = r_alias & ~use_cert
    uncertified = use_cert & ~cert.ran
    tests = [
        ~c.any_anchor,
        c.max_score < p.score_floor,
        g.n_groups == 0,
        g.seen.astype(jnp.float32) < b_min,
        ~gate_w,
        g.spread > p.sigma_max,
        (m < delta_min) & lat_ok,
        decisive & p_alias,
        decisive & r_alias,
        decisive & dominated,
        decisive & (blocked | uncertified),
        decisive,
    ]
    multi = jnp.where(g.n_groups >= 2, lattice.MULTIMODAL, lattice.KIND_NONE)
    states = [DEFER] * 6 + [AMBIGUOUS] * 5 + [COMMIT]
    kinds = [lattice.KIND_NONE] * 6 + [
        lattice.TRANSLATION,
        lattice.TRANSLATION,
        lattice.ROTATION,
        lattice.MULTIMODAL,
        jnp.where(blocked, c_kind, multi),
        lattice.KIND_NONE,
    ]
    reasons = [1, 2, 3, 4, 5, 6, 0, 0, 0, 12, 11, 0]
    state = jnp.select(tests, states, AMBIGUOUS).astype(jnp.int32)
    kind = jnp.select(tests, kinds, multi).astype(jnp.int32)
    reason = jnp.select(tests, reasons, 0).astype(jnp.int32)
    tau = jnp.select(
        [tests[6], tests[7], tests[10] & blocked], [lat_tau, p_tau, c_tau], jnp.zeros_like(lat_tau)
    )
    zero_i = jnp.int32(0)
    return Decision(
        state=state,
        kind=kind,
        anchor=g.t_star,
        tau=jnp.where(kind == lattice.TRANSLATION, tau, 0.0),
        b1=g.b1,
        b2=b2,
        margin=g.b1 - b2,
        n_groups=g.n_groups,
        n_champions=c.n_champions,
        spread=g.spread,
        rooms=pr.rooms,
        c_winner=pr.c_winner,
        winner_gate=pr.c_winner >= p.tau_c,
        probe_alias=gate_alias,
        probe_c=jnp.maximum(p_c, r_c),
        reason=reason,
        max_score=c.max_score,
        alias_motion=jnp.where(
            kind == lattice.ROTATION,
            jnp.where(use_cert, se2.compose(rival, se2.inverse(g.t_star)), pr.motion),
            jnp.zeros_like(pr.motion),
        ),
        competitor=jnp.where(
            blocked,
            rival,
            jnp.where(jnp.any(counted), g.anchor[runner_up], jnp.zeros_like(rival)),
        ),
        has_competitor=(state == AMBIGUOUS) & (blocked | jnp.any(counted)),
        n_live=jnp.sum(live_c).astype(jnp.int32),
        certified=cert.ran,
        searched=jnp.bool_(False),
        n_rejected=zero_i,
        dropped=zero_i,
        llr=jnp.float32(jnp.nan),
        test_anchor=jnp.zeros_like(g.t_star),
    )
