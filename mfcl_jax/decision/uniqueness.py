"""Is the path seen so far explained by one placement in the building, and by no other?

A count of windows (``b_min`` of them, sharing no scan) is a proxy for "no other place
explains what I have seen"; this module checks that statement, with a stated error model
(``frontend.path_llr``), so a lane may commit as soon as it holds, whatever the count:

1. the candidates: every placement of the whole path that the global search finds
   (``frontend.path_search``: exhaustive over headings at 5 deg and translations on a coarse
   cell of 0.4-0.5 m, then polished), the newest window's best registrations, the consensus
   winner ``T*`` and the probe's aliases of it (the building's known symmetries);
2. each admissible one (the probe's aliases the gate rejects are not candidates; ``fit``) is
   fitted to the path under the observation model (``path_llr.refine``, a first
   round of 0.3 m / 3 deg steps, then the fit's own rounds to 1.5 cm / 0.15 deg), and the best
   ``A*`` is compared with the best candidate outside its neighbourhood (farther than 1 m or
   5 deg, the line a commit is judged by): ``llr = L(A*) - L(competitor)``. A candidate
   on ``A*``'s own peak climbs into ``A*``, so the best 3 of 12 placements just past the
   line around it (the robot moved 1.05 m or turned 5.25 deg) climb while they stay
   outside: where the peak is wider than the line (a short path that does not tell a 5 deg
   turn apart), its edge is the competitor, and the test waits until the path narrows it;
3. the statement holds when ``llr >= log(1 / alpha)`` (a lane's knob, ``lanes``): under the
   model, a wrong placement reaches that margin against the truth with probability at most
   ``alpha`` (Wald's bound for one sequential test; with a search that covers every
   placement it is the bound for the best wrong one).

Vetoes (the layer's checks, kept): ``A*`` must pass the feasibility gate, agree with the
newest window's champion, and not disagree with a consensus winner of two or more windows.

The search covers every placement on its grid, then the peaks are polished, so a competitor
narrower than the grid's cell (0.4-0.5 m, 5 deg) can be missed: the certificate is
exhaustive at that resolution, not a bound over the continuum (``experiments.audit.path_certify``
bounds the continuum, as an audit: ``experiments.audit.certificate``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import gate, rivals
from mfcl_jax.frontend import path_llr
from mfcl_jax.frontend.path_llr import LLRParams

__all__ = [
    "UniqueParams",
    "UniqStats",
    "DEFAULT_UNIQUE",
    "uniqueness",
    "fit",
    "edge",
    "skipped",
    "vetoes",
]


@dataclass(frozen=True)
class UniqueParams:
    """Settings of the uniqueness test (static; one setting for every building)."""

    near_xy: float = 1.0  # m: placements this close to A* are the same answer
    near_deg: float = 5.0
    # placements kept from the global search: all it returns (path_search's n_out); ranked by
    # its own coarse score, a competitor can sit below 8 (ring-1/B/s1's half-turn was 12th)
    n_search: int = 12
    n_newest: int = 3  # best registrations of the newest window
    max_tests: int = 8  # tests per odometry segment (the count rule takes over after)
    n_edge: int = 3  # placements of the rim around A* fitted (its best by L): its edge
    # candidates fitted at once: the admissible ones are packed first and fitted in blocks of
    # this many until none is left (the probe's alias slots, a few hundred in a plan of many
    # congruent rooms, are mostly inadmissible: fitting every slot cost 9 in 10 of a test)
    fit_block: int = 32
    llr: LLRParams = LLRParams()
    # the fit's rounds of 27 poses, (m, deg): a first round of 0.3 m / 3 deg reaches a peak
    # up to about 0.6 m and 6 deg from a candidate, where a competitor narrower than the
    # search's cell can sit (the branch and bound's audit found three such; 27 more
    # evaluations of L per candidate)
    polish: tuple = ((0.3, 3.0), *path_llr.REFINE_STEPS)


DEFAULT_UNIQUE = UniqueParams()


@dataclass(frozen=True)
class UniqStats:
    """The test at one window (``ran`` false: not tested; everything else zero)."""

    anchor: jax.Array  # (3,) A*
    competitor: jax.Array  # (3,) the best candidate outside A*'s neighbourhood
    llr: jax.Array  # () L(A*) - L(competitor); +inf without a competitor
    vetoed: jax.Array  # () bool a veto holds (gate, champion, consensus winner)
    c_gate: jax.Array  # () gate consistency of A*
    ran: jax.Array  # () bool


jax.tree_util.register_dataclass(
    UniqStats, data_fields=list(UniqStats.__dataclass_fields__), meta_fields=[]
)


def skipped() -> UniqStats:
    z3 = jnp.zeros(3, jnp.float32)
    f = jnp.float32(0.0)
    return UniqStats(z3, z3, f, jnp.bool_(False), f, jnp.bool_(False))


def _rim(best, x_now, centre, u: UniqueParams):
    """Placements just past ``best``'s neighbourhood, judged where the robot is now: the
    robot moved 1.05 ``near_xy`` in 8 directions, or turned by 1.05 ``near_deg`` either way
    about itself or about ``centre`` (the path's returns, plan frame). ``(12, 3)``."""
    now = se2.compose(best, x_now)
    r, th = 1.05 * u.near_xy, math.radians(1.05 * u.near_deg)
    phi = jnp.arange(8, dtype=jnp.float32) * (math.pi / 4)
    moved = now + r * jnp.stack([jnp.cos(phi), jnp.sin(phi), jnp.zeros_like(phi)], -1)
    q = jnp.stack([now[:2], now[:2], centre, centre])
    s = jnp.asarray([th, -th, th, -th], jnp.float32)
    turned = jnp.concatenate([q + se2.rotate(s, now[:2] - q), (now[2] + s)[:, None]], -1)
    return se2.compose(jnp.concatenate([moved, turned]), se2.inverse(x_now))


def _outside(a, best, x_now, u: UniqueParams):
    """Placements ``a (*, 3)`` outside ``best``'s neighbourhood, judged where the robot is."""
    dxy, dth = se2.distance_pair(se2.compose(a, x_now), se2.compose(best, x_now))
    return (dxy > u.near_xy) | (dth > math.radians(u.near_deg))


def edge(best, x_now, pe, fields, u: UniqueParams = DEFAULT_UNIQUE):
    """The best placement just outside ``best``'s neighbourhood on its own peak, and its
    ``L``: the ``_rim``'s ``u.n_edge`` best placements, each climbing (``u.polish``) while
    it stays outside."""
    w = jnp.maximum(pe.pw, 0.0)
    c = jnp.sum(pe.pts * w[:, None], 0) / jnp.maximum(jnp.sum(w), 1e-9)
    rim = _rim(best, x_now, se2.apply(best, c[None])[0], u)
    L0 = jax.vmap(lambda a: path_llr.log_likelihood(a, pe, fields, u.llr))(rim)
    rim = rim[jax.lax.top_k(L0, u.n_edge)[1]]
    allowed = lambda a: _outside(a, best, x_now, u)  # noqa: E731
    R, L = jax.vmap(lambda a: path_llr.refine(a, pe, fields, u.llr, u.polish, allowed))(rim)
    L = jnp.where(allowed(R), L, -jnp.inf)
    i = jnp.argmax(L)
    return R[i], L[i]


def fit(cand, ok, pe, fields, u: UniqueParams = DEFAULT_UNIQUE):
    """Each admissible candidate ``cand (N, 3)`` fitted to the path (``path_llr.refine``,
    ``u.polish``) and its ``L``; the others are returned as they are, with ``L = -inf``.

    Only the admissible ones are fitted: packed first, in blocks of ``u.fit_block`` while any
    is left (one block unless the probe admits many aliases: 2.4 on average in Office_A).
    """
    n = cand.shape[0]
    b = min(u.fit_block, n)
    n_pad = -(-n // b) * b
    order = jnp.argsort(~ok, stable=True)  # admissible first, in their order
    c = jnp.zeros((n_pad, 3), cand.dtype).at[:n].set(cand[order])
    n_ok = jnp.sum(ok)
    one = jax.vmap(lambda a: path_llr.refine(a, pe, fields, u.llr, u.polish))

    def block(carry):
        i, A, L = carry
        a, l_ = one(jax.lax.dynamic_slice_in_dim(c, i * b, b))
        A = jax.lax.dynamic_update_slice_in_dim(A, a, i * b, 0)
        return i + 1, A, jax.lax.dynamic_update_slice_in_dim(L, l_, i * b, 0)

    L0 = jnp.full((n_pad,), -jnp.inf, jnp.float32)
    _, A, L = jax.lax.while_loop(lambda x: x[0] * b < n_ok, block, (0, c, L0))
    A = jnp.zeros_like(cand).at[order].set(A[:n])
    L = jnp.full((n,), -jnp.inf, L.dtype).at[order].set(L[:n])
    return jnp.where(ok[:, None], A, cand), jnp.where(ok, L, -jnp.inf)


def uniqueness(h, path, maps, fields, n_img: int, t_star, aliases, aliases_ok, champion,
               champion_ok, winner_b1, tau_c, delta_xy, delta_theta,
               u: UniqueParams = DEFAULT_UNIQUE) -> UniqStats:  # fmt: skip
    """The test on the layer's history ``h`` and path (module docstring).

    Args:
        h: ``History``; path: ``Path`` (its poses gate ``A*``); maps: ``DecisionMaps``;
        fields: ``PlanFields`` of the search; n_img: static image side of the search.
        t_star: ``(3,)`` consensus winner; aliases, aliases_ok: ``(A, 3)``, ``(A,)`` the
            probe's aliases of it; champion, champion_ok: the newest window's champion.
        winner_b1: ``()`` the consensus winner's scan-disjoint support.
        tau_c: gate threshold; delta_xy, delta_theta: grouping tolerances (the vetoes).
    """
    k = h.n - 1
    rp = rivals.RivalParams(n_rivals=u.n_search, keep_ratio=0.0)
    found, found_ok = rivals.search(h.ev_points, h.ev_origins, h.ev_mask, h.X, fields, n_img, rp)
    Hk, sk, mk = h.H[k], h.score[k], h.mask[k]
    top = jnp.argsort(jnp.where(mk, -sk, jnp.inf))[: u.n_newest]
    cand = jnp.concatenate([found, Hk[top], t_star[None], aliases]).astype(jnp.float32)
    ok = jnp.concatenate([found_ok, mk[top], jnp.ones(1, bool), aliases_ok])
    pe = path_llr.path_evidence(h.ev_points, h.ev_origins, h.ev_mask, h.X, path.dist, u.llr)
    A, L = fit(cand, ok, pe, fields, u)
    i = jnp.argmax(L)
    best = A[i]
    # judged where the robot is now: the same answer is within the line a commit is judged by
    x_now = h.X[k]
    lc = jnp.where(ok & _outside(A, best, x_now, u), L, -jnp.inf)
    # the candidates climb into A* from its own peak: its edge is searched apart
    e, le = edge(best, x_now, pe, fields, u)
    A, lc = jnp.concatenate([A, e[None]]), jnp.concatenate([lc, le[None]])
    j = jnp.argmax(lc)
    llr = L[i] - lc[j]
    vetoed, c_gate = vetoes(best, path, maps, champion, champion_ok, t_star, winner_b1, tau_c,
                            delta_xy, delta_theta)  # fmt: skip
    return UniqStats(best, A[j], llr, vetoed | ~jnp.any(ok), c_gate, jnp.bool_(True))


def vetoes(best, path, maps, champion, champion_ok, t_star, winner_b1, tau_c, delta_xy,
           delta_theta):  # fmt: skip
    """``(vetoed, c_gate)``: the layer's checks on an early commit to ``best``: it passes the
    feasibility gate over the path, the newest window's champion agrees with it, and no
    consensus winner of two or more windows disagrees (anchors, within the grouping
    tolerances ``delta_xy``, ``delta_theta``)."""
    pvalid = jnp.arange(path.pose.shape[0]) < path.n
    walk = gate.extend_walk(maps, best[None], path.pose, pvalid, gate.start_walk((1,)))
    c_gate = walk.consistency()[0]
    cxy, cth = se2.distance_pair(champion, best)
    agrees = champion_ok & (cxy <= delta_xy) & (cth <= delta_theta)
    txy, tth = se2.distance_pair(t_star, best)
    contradicted = (winner_b1 >= 2) & ((txy > delta_xy) | (tth > delta_theta))
    return (c_gate < tau_c) | ~agrees | contradicted, c_gate
