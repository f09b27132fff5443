"""The selective decision at one prefix (Algorithm 1), as a pure array function.

``decide_prefix`` maps the candidates of windows ``1..k``, their gate consistencies at prefix
``k`` and the trajectory up to ``window_end[k]`` to one ``Decisions`` record. It holds no state, so
the batch path (``vmap`` over prefixes) and the streaming path (latest prefix only) agree.

Order of tests (first that fires wins):

1. no valid candidate                                  -> DEFER ("no anchors")
2. best score below the floor                          -> DEFER ("below floor")
3. no admitted champion (all gated)                    -> DEFER ("no feasible champion")
4. fewer than ``b_min`` scan-disjoint windows have a champion (any group): the evidence is
   not saturated yet; no room labels needed, so occupancy maps work -> DEFER ("unsaturated")
5. T* fails the gate / spread > sigma_max              -> DEFER ("winner infeasible"/"spread")
6. margin < delta_min and tied groups form a lattice   -> AMBIGUOUS(translation, tau)
7. B1 >= b_min and margin >= delta_min: probe aliases; an admissible translational one
   -> AMBIGUOUS(translation, tau), else an admissible rotational one (``g T*`` for a
   rotational self-motion ``g`` of the building) -> AMBIGUOUS(rotation; ``tau`` zero, ``g`` in
   ``Decisions.alias_motion``), else COMMIT(T*)
8. otherwise -> AMBIGUOUS (multimodal with >= 2 groups, no kind with one group)

With the certification on (``ours``), the runner-up support ``B2`` in the margin (tests 6-7)
counts only the groups whose anchors the scans have not ruled out (``certify``: some window
contradicts the group's anchor by ``cert_margin`` and none favours it): a group of champions
that every re-scored window contradicts is not an explanation of the path, however many
windows' top-1 it was. Without the certification (``paper``, ``no_probe``, ...) every group
counts, as in the paper. ``Decisions.b2``/``margin`` report the counts the rule used.

``T*`` (the reported anchor, ``Decisions.anchor``) is the mean of the winner's most recent
champions (``DecisionParams.recent``); tests 5 and 7 (winner gate, probe) use it because it
is the anchor a commit hands over. ``rooms`` (rooms spanned under ``T*``) is reported as a
diagnostic only. Grouping, ``B_m``, the margin, the
spread (test 5, about the all-member mean) and the lattice (all-member group means) are as
in the paper.

The work splits in two: ``prefix_core`` (champions, groups, the lattice over all groups and
the probe) depends only on the prefix, the thresholds and the gate flag; ``finish`` applies a
variant's probe flag and floors (and the tied-group lattice, which depends on ``delta_min``).
The evaluator shares one core among every variant with the same gate flag.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.decision import certify, consensus, lattice, probe

__all__ = [
    "DEFER",
    "AMBIGUOUS",
    "COMMIT",
    "STATE_NAMES",
    "REASONS",
    "KNOBS",
    "DecisionParams",
    "Decisions",
    "PrefixCore",
    "prefix_core",
    "finish",
    "certify_core",
    "decide_prefix",
]

# The thresholds a threshold-set axis may vary (each policy's own knob): read only after the
# shared decision core, by ``finish`` and the baselines.
KNOBS = ("b_min", "delta_min", "confidence_ratio", "support_ratio", "cert_margin")

DEFER, AMBIGUOUS, COMMIT = 0, 1, 2
STATE_NAMES = {DEFER: "DEFER", AMBIGUOUS: "AMBIGUOUS", COMMIT: "COMMIT"}
REASONS = {
    0: "",
    1: "no anchors",
    2: "below floor",
    3: "no feasible champion",
    4: "unsaturated",
    5: "winner infeasible",
    6: "spread",
    7: "alias without period",
    8: "not triggered",
    9: "commit contradicted",
    10: "commit infeasible",
    11: "competitor not ruled out",
    12: "winner contradicted",
    13: "commit stale",
}


@dataclass(frozen=True)
class DecisionParams:
    """Decision-layer thresholds (paper Table I defaults). Every field is a traced leaf.

    Angles are in radians. ``score_floor`` drops candidates (and defers when every score is
    below it); ``confidence_ratio`` and ``support_ratio`` parametrise the baselines.
    ``recent`` is how many of the winner's most recent champions are averaged into the
    reported anchor ``T*`` (``<= 0``: all of them, the paper's ``T*``); see ``consensus``.
    Beyond the paper: ``cert_margin`` (a knob) is the verification-score advantage by which a
    window contradicts or favours an explanation and ``cert_sigma`` the score's kernel width
    (``certify``); ``drift_xy`` (fraction of the distance) and ``drift_theta`` (rad per metre)
    widen the grouping tolerances with the distance travelled between two champions' windows
    (``consensus``): an odometry of that quality keeps one place's anchors in one group.
    """

    delta_xy: float = 1.5
    delta_theta: float = float(np.deg2rad(18.0))
    b_min: float = 3.0
    delta_min: float = 2.0
    sigma_max: float = 3.0
    tau_c: float = 0.50
    n_max: float = 3.0
    gamma: float = 0.075
    eps_t: float = 2.5
    eps_theta: float = float(np.deg2rad(12.0))
    score_floor: float = 0.0
    confidence_ratio: float = 1.2
    support_ratio: float = 1.5
    recent: float = 3.0
    cert_margin: float = 0.05
    cert_sigma: float = 0.07
    drift_xy: float = 0.02
    drift_theta: float = float(np.deg2rad(0.1))

    def replace(self, **kw) -> DecisionParams:
        return replace(self, **kw)

    def as_arrays(self) -> DecisionParams:
        """Leaves as float32 JAX scalars (what kernels expect)."""
        vals = {f.name: jnp.float32(getattr(self, f.name)) for f in fields(self)}
        return DecisionParams(**vals)

    @staticmethod
    def stack(params: list[DecisionParams]) -> DecisionParams:
        """A threshold set axis ``(S,)`` from a list of parameter sets.

        The sets may differ only in ``KNOBS`` (the decision core is shared by every set).
        """
        names = [f.name for f in fields(DecisionParams)]
        for p in params:
            for n in names:
                if not np.isfinite(float(getattr(p, n))):
                    raise ValueError(f"DecisionParams: non-finite {n}={getattr(p, n)!r}")
                if n not in KNOBS and float(getattr(p, n)) != float(getattr(params[0], n)):
                    raise ValueError(
                        f"DecisionParams.stack: sets may differ only in {KNOBS}; "
                        f"{n}={getattr(p, n)!r} differs from {getattr(params[0], n)!r}"
                    )
        vals = {n: jnp.asarray([float(getattr(p, n)) for p in params], jnp.float32) for n in names}
        return DecisionParams(**vals)


jax.tree_util.register_dataclass(
    DecisionParams,
    data_fields=[f.name for f in fields(DecisionParams)],
    meta_fields=[],
)


@dataclass(frozen=True)
class Decisions:
    """One decision (scalars; batched leading axes ``(R, K, S, V)`` in the evaluator)."""

    state: jax.Array  # int32 DEFER/AMBIGUOUS/COMMIT
    kind: jax.Array  # int32 lattice.KIND_*
    anchor: jax.Array  # (3,) T* (ours) or the policy's pick (baselines)
    tau: jax.Array  # (2,) zero unless kind == translation
    b1: jax.Array
    b2: jax.Array
    margin: jax.Array
    n_groups: jax.Array
    n_champions: jax.Array
    spread: jax.Array
    rooms: jax.Array  # rooms spanned under T*
    c_winner: jax.Array
    winner_gate: jax.Array  # bool
    probe_alias: jax.Array  # bool
    probe_c: jax.Array
    reason: jax.Array  # int32 key of REASONS
    max_score: jax.Array
    alias_motion: jax.Array  # (3,) self-motion g of the rotational alias; zero unless rotation
    # (3,) the strongest competing explanation of an AMBIGUOUS decision: the competitor the
    # certification did not rule out (the one with the smallest largest advantage), else the
    # runner-up consensus group counted in B2 (a held commit that a new winner contradicts,
    # in ``machine``); zero when ``has_competitor`` is false
    competitor: jax.Array
    has_competitor: jax.Array  # bool: an AMBIGUOUS decision with a competitor (false otherwise)
    n_live: jax.Array  # int32 competitors not ruled out (0 unless certification blocked)


jax.tree_util.register_dataclass(
    Decisions, data_fields=list(Decisions.__dataclass_fields__), meta_fields=[]
)


@dataclass(frozen=True)
class PrefixCore:
    """What a decision at one prefix needs before the variant's floors and probe flag apply.

    It depends on the prefix, the thresholds and the gate flag only, so the evaluator computes
    it once per gate mode and finishes every variant from it (``finish``).
    """

    any_anchor: jax.Array  # () bool
    max_score: jax.Array  # ()
    n_champions: jax.Array  # () int32
    groups: consensus.Groups
    fit: lattice.LatticeFit  # residual tests of the group anchors (shared by every mask)
    all_ok: jax.Array  # () bool lattice over every live group
    all_tau: jax.Array  # (2,)
    probe_result: probe.ProbeResult  # every probe period on (the variant may switch it off)
    admitted: jax.Array  # (K, J) bool candidates of the prefix past the floor (and the gate)


jax.tree_util.register_dataclass(
    PrefixCore, data_fields=list(PrefixCore.__dataclass_fields__), meta_fields=[]
)


def prefix_core(
    k, H, score, mask, cons, traj, traj_mask, bounds, maps, p: DecisionParams, use_gate, n_cap=3
) -> PrefixCore:
    """Champions, groups, the all-group lattice and the probe at prefix ``k``.

    Args: as ``decide_prefix``.
    """
    wstart, wend = bounds
    end = wend[k]
    kk = H.shape[0]
    visible = mask & (jnp.arange(kk) <= k)[:, None]
    any_anchor = jnp.any(visible)
    max_score = jnp.max(jnp.where(visible, score, -jnp.inf))
    max_score = jnp.where(any_anchor, max_score, 0.0)
    admitted = visible & (score >= p.score_floor) & ((cons >= p.tau_c) | ~use_gate)
    ch = consensus.champions(H, score, admitted)
    step = jnp.linalg.norm(jnp.diff(traj[:, :2], axis=0), axis=-1)
    s_traj = jnp.concatenate([jnp.zeros(1, traj.dtype), jnp.cumsum(jnp.where(traj_mask[1:], step,
                                                                              0.0))])  # fmt: skip
    g = consensus.group(
        ch, p.delta_xy, p.delta_theta, p.recent, wstart, wend, s_traj[wend],
        (p.drift_xy, p.drift_theta),
    )  # fmt: skip
    live = jnp.arange(kk) < g.n_groups
    fit = lattice.prepare(g.anchor, g.winner, maps.offsets, p.eps_t)
    all_ok, all_tau = lattice.detect_from(
        fit, live, g.winner, maps.offsets, maps.offsets_mask, p.eps_t, p.eps_theta
    )
    taus = jnp.concatenate([all_tau[None], maps.generators.astype(all_tau.dtype)], axis=0)
    taus_mask = jnp.concatenate([all_ok[None], maps.generators_mask])
    # The reported (recency) anchor is the one committed, so it is the one gated and probed.
    pr = probe.probe(
        maps, g.t_star, taus, taus_mask, traj, traj_mask, end, p.tau_c, p.gamma, p.n_max, n_cap
    )
    n_ch = jnp.sum(ch.has).astype(jnp.int32)
    return PrefixCore(any_anchor, max_score, n_ch, g, fit, all_ok, all_tau, pr, admitted)


def certify_core(k, core: PrefixCore, H, score, X, evidence, bounds, maps, p, rivals=None,
                 n_slots=12):  # fmt: skip
    """``certify.CertStats`` of the competitors of the core's ``T*`` at prefix ``k``: the
    probe's gate-admissible aliases, the other groups, each window's runner-up and the
    global search's rivals ``(anchors (E, 3), found_at (E,))`` found at or before ``k``."""
    g = core.groups
    kk = g.size.shape[0]
    others = (jnp.arange(kk) < g.n_groups) & (jnp.arange(kk) != g.winner)
    pr = core.probe_result
    r_anchor, r_ok = (None, None) if rivals is None else (rivals[0], rivals[1] <= k)
    comp, ok = certify.competitors(
        g.t_star, pr.aliases, pr.aliases_ok, g.anchor, others, H, score, core.admitted, X[k],
        r_anchor, r_ok,
    )  # fmt: skip
    return certify.certify(k, g.t_star, comp, ok, X, evidence, bounds, maps, p, n_slots)


def finish(
    core: PrefixCore,
    cert: certify.CertStats,
    maps,
    p: DecisionParams,
    use_gate,
    use_probe,
    use_cert,
    b_min,
    delta_min,
) -> Decisions:
    """Applies a variant (gate, probe and certification flags, commit floors) to a
    ``PrefixCore`` and its ``CertStats``.

    ``use_gate`` must be the flag ``core`` was computed with. With the certification on, the
    probe's aliases are judged by the scans (``certify``) rather than by the gate alone.
    """
    g = core.groups
    kk = g.size.shape[0]
    live = jnp.arange(kk) < g.n_groups
    m = p.cert_margin
    against = cert.max_adv >= m
    favoured = cert.min_adv <= -m
    live_c = cert.valid & ~(against & ~favoured) & use_cert
    # Under the certification a runner-up group counts against the winner only while the
    # scans have not ruled its anchor out. ``certify.competitors`` lists the probe's aliases,
    # the groups' anchors, the runner-ups and the rivals, in that order: slots A .. A + K.
    n_a = core.probe_result.aliases.shape[0]
    rival_group = live & (jnp.arange(kk) != g.winner)
    counted = rival_group & (live_c[n_a : n_a + kk] | ~use_cert)
    b2 = jnp.max(jnp.where(counted, g.indep, 0)).astype(g.b2.dtype)
    runner_up = jnp.argmax(jnp.where(counted, g.indep, -1))  # the group B2 counts
    tied = (counted | (jnp.arange(kk) == g.winner)) & live
    tied = tied & ((g.b1 - g.indep).astype(jnp.float32) < delta_min)
    lat_ok, lat_tau = lattice.detect_from(
        core.fit, tied, g.winner, maps.offsets, maps.offsets_mask, p.eps_t, p.eps_theta
    )
    pr = core.probe_result
    # probe off == every probe period masked: no alias, zero period and alias consistency
    p_alias = pr.alias & use_probe
    p_tau = jnp.where(use_probe, pr.tau, jnp.zeros_like(pr.tau))
    p_c = jnp.where(use_probe, pr.c_alias, jnp.zeros_like(pr.c_alias))
    r_alias = pr.rot_alias & use_probe
    r_c = jnp.where(use_probe, pr.c_rot, jnp.zeros_like(pr.c_rot))
    gate_w = (pr.c_winner >= p.tau_c) | ~use_gate
    b1, margin = g.b1.astype(jnp.float32), (g.b1 - b2).astype(jnp.float32)
    decisive = (b1 >= b_min) & (margin >= delta_min)
    # certification: a competitor is ruled out when some window contradicts it and none
    # favours it; T* is dominated when a competitor is favoured somewhere, contradicted nowhere
    dominated = jnp.any(cert.valid & favoured & ~against) & use_cert
    strongest = jnp.argmin(jnp.where(live_c, cert.max_adv, jnp.inf))
    rival = cert.anchor[strongest]
    c_kind, c_tau = certify.relation(g.t_star, rival)
    blocked = jnp.any(live_c) | dominated
    # without the certification the paper's probe decides alone (gate-admissible aliases)
    gate_alias = p_alias | r_alias  # reported either way (diagnostic)
    p_alias = p_alias & ~use_cert
    r_alias = r_alias & ~use_cert
    tests = [
        ~core.any_anchor,
        core.max_score < p.score_floor,
        g.n_groups == 0,
        g.seen.astype(jnp.float32) < b_min,
        ~gate_w,
        g.spread > p.sigma_max,
        (margin < delta_min) & lat_ok,
        decisive & p_alias,
        decisive & r_alias,
        decisive & dominated,
        decisive & blocked,
        decisive,
    ]
    multi = jnp.where(g.n_groups >= 2, lattice.MULTIMODAL, lattice.KIND_NONE)
    states = [DEFER] * 6 + [AMBIGUOUS] * 5 + [COMMIT]
    kinds = [lattice.KIND_NONE] * 6 + [
        lattice.TRANSLATION,
        lattice.TRANSLATION,
        lattice.ROTATION,
        lattice.MULTIMODAL,
        c_kind,
        lattice.KIND_NONE,
    ]
    reasons = [1, 2, 3, 4, 5, 6, 0, 0, 0, 12, 11, 0]
    state = jnp.select(tests, states, AMBIGUOUS).astype(jnp.int32)
    kind = jnp.select(tests, kinds, multi).astype(jnp.int32)
    reason = jnp.select(tests, reasons, 0).astype(jnp.int32)
    tau = jnp.select(
        [tests[6], tests[7], tests[10]], [lat_tau, p_tau, c_tau], jnp.zeros_like(lat_tau)
    )
    return Decisions(
        state=state,
        kind=kind,
        anchor=g.t_star,
        tau=jnp.where(kind == lattice.TRANSLATION, tau, 0.0),
        b1=g.b1,
        b2=b2,
        margin=g.b1 - b2,
        n_groups=g.n_groups,
        n_champions=core.n_champions,
        spread=g.spread,
        rooms=pr.rooms,
        c_winner=pr.c_winner,
        winner_gate=pr.c_winner >= p.tau_c,
        probe_alias=gate_alias,
        probe_c=jnp.maximum(p_c, r_c),
        reason=reason,
        max_score=core.max_score,
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
    )


def decide_prefix(
    k, H, score, mask, cons, traj, traj_mask, bounds, X, evidence, maps, p: DecisionParams,
    flags, n_cap: int = 3, rivals=None,
) -> Decisions:  # fmt: skip
    """Our decision at prefix ``k`` (0-based window index), before the commit machine.

    Args:
        k: ``()`` int32 prefix (windows ``0..k`` are visible).
        H: ``(K, J, 3)`` anchors; score: ``(K, J)``; mask: ``(K, J)`` valid candidates
            (padded windows already masked).
        cons: ``(K, J)`` gate consistency of each candidate at this prefix.
        traj: ``(T, 3)``; traj_mask: ``(T,)``.
        bounds: ``(start (K,), end (K,))`` first and last trajectory sample of every window.
        X: ``(K, 3)`` odometry pose of each window's last scan.
        evidence: ``(points, origins, mask)`` ``(K, P, ...)`` the windows' evidence samples.
        maps: ``DecisionMaps``; p: scalar ``DecisionParams``.
        flags: ``(use_gate, use_probe, use_cert, b_min, delta_min)`` of the variant (traced;
            floors already resolved against ``p``).
        n_cap: static probe shift capacity.
        rivals: ``(anchors (E, 3), found_at (E,))`` the global search's rivals (``rivals``),
            each a competitor from the prefix it was found at; None for none.
    """
    use_gate, use_probe, use_cert, b_min, delta_min = flags
    core = prefix_core(k, H, score, mask, cons, traj, traj_mask, bounds, maps, p, use_gate, n_cap)
    cert = certify_core(k, core, H, score, X, evidence, bounds, maps, p, rivals)
    return finish(core, cert, maps, p, use_gate, use_probe, use_cert, b_min, delta_min)
