"""Translational lattice detection over consensus groups.

For two group anchors with nearly equal yaw (within ``eps_theta``), ``Delta_ab = T_a^-1 T_b``
is a pure translation; we work with its image in the floor-plan frame, ``t_b - t_a`` (equal
to ``T_b T_a^-1`` for equal yaw), because the period is validated against room offsets,
which live in that frame. The groups form a coherent lattice with period ``tau`` when every
contender satisfies ``t_a - t_w ~ k_a tau`` (``k_a`` integer, residual ``<= eps_t``) relative to
the winner ``w``; pairwise coherence then follows (within ``2 eps_t``).

``tau`` is estimated from the anchors: generators ``(t_a - t_w) / n`` for every contender and
``n = 1..n_sub``; each coherent generator is refined by least squares over the contenders,
``tau = sum k_a d_a / sum k_a^2``, and kept only if it lies within ``eps_t`` of a congruent-room
offset ``o`` of the floor plan and the anchors are coherent with ``o`` itself; the reported
``tau`` is the least-squares refit with the multiples of ``o``. Among the valid ones the shortest
room offset is the fundamental. A sub-harmonic ``tau / n`` therefore survives only if it is
itself a room offset. ``tau`` is reported with a
canonical sign (positive x, or positive y when x is zero).

Every residual test depends on the anchors only, not on which groups contend, so it is done
once (``prepare``) and each contender mask costs masked reductions (``detect_from``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.sparse_cond import sparse_cond

__all__ = [
    "KIND_NONE",
    "TRANSLATION",
    "MULTIMODAL",
    "ROTATION",
    "MIRROR",
    "KIND_NAMES",
    "LatticeFit",
    "prepare",
    "detect_from",
    "detect",
]

# Kind codes of AMBIGUOUS. Rotation classes come from the alias probe (quarter-turn
# self-motions of the building, see ``symmetry``); the mirror class is reserved (not detected);
# the storey class marks a place shared by congruent storeys (``decision.storey``).
KIND_NONE, TRANSLATION, MULTIMODAL, ROTATION, MIRROR, STOREY = 0, 1, 2, 3, 4, 5
KIND_NAMES = {
    KIND_NONE: None,
    TRANSLATION: "translation",
    MULTIMODAL: "multimodal",
    ROTATION: "rotation",
    MIRROR: "mirror",
    STOREY: "storey",
}


@dataclass(frozen=True)
class LatticeFit:
    """The contender-independent part of ``detect`` for one set of group anchors.

    Integer multiples and residual tests of every generator (``C = G n_sub``) and of every room
    offset against every group. ``detect_from`` turns it into a verdict for any contender mask
    with masked reductions only, so several masks (all groups, tied groups under different
    floors) share one fit.
    """

    d: jax.Array  # (G, 2) anchor translations relative to the winner's
    dth: jax.Array  # (G,) heading difference to the winner
    gen: jax.Array  # (C, 2) candidate periods (t_a - t_w) / n
    gen_len_ok: jax.Array  # (C,) bool non-zero period
    k_gen: jax.Array  # (C, G) integer multiples of each generator
    ok_gen: jax.Array  # (C, G) bool residual <= eps_t
    k_off: jax.Array  # (P, G) integer multiples of each room offset
    ok_off: jax.Array  # (P, G) bool residual <= eps_t


jax.tree_util.register_dataclass(
    LatticeFit, data_fields=list(LatticeFit.__dataclass_fields__), meta_fields=[]
)


def _multiples(d, v, eps_t):
    """Integer multiples ``k (C, G)`` of periods ``v (C, 2)`` nearest ``d (G, 2)``; fit mask."""
    v2 = jnp.maximum(jnp.sum(v * v, axis=-1), 1e-12)
    k = jnp.round(jnp.einsum("gd,cd->cg", d, v) / v2[:, None])
    res = jnp.linalg.norm(d[None] - k[..., None] * v[:, None, :], axis=-1)
    return k, res <= eps_t


def prepare(anchor, winner, offsets, eps_t, n_sub: int = 3) -> LatticeFit:
    """``LatticeFit`` of group anchors ``(G, 3)`` relative to group ``winner``."""
    g = anchor.shape[0]
    ref = anchor[winner]
    d = anchor[:, :2] - ref[:2]  # (G, 2)
    _, dth = se2.distance_pair(anchor, ref)
    n = jnp.arange(1, n_sub + 1, dtype=anchor.dtype)
    gen = (d[:, None, :] / n[None, :, None]).reshape(g * n_sub, 2)  # (C, 2)
    k_gen, ok_gen = _multiples(d, gen, eps_t)
    k_off, ok_off = _multiples(d, offsets.astype(d.dtype), eps_t)
    return LatticeFit(
        d, dth, gen, jnp.linalg.norm(gen, axis=-1) > 1e-6, k_gen, ok_gen, k_off, ok_off
    )


# Contenders besides the winner whose generators ``detect_from`` reads in its compact form; a
# mask with more takes the full form (``sparse_cond``: only those rows pay for it).
SLOTS = 8


def detect_from(
    fit: LatticeFit, contender, winner, offsets, offsets_mask, eps_t, eps_theta, n_sub: int = 3
):
    """``detect`` for one contender mask from a shared ``LatticeFit`` (same arguments).

    Only generators of contenders can be valid, so where at most ``SLOTS`` groups contend
    besides the winner, only theirs are tested (in index order: the same pick among ties);
    a mask with more contenders is tested on every generator. Lanes evaluate it once each, so
    this is most of what a lane costs."""
    g = contender.shape[0]
    others = contender & (jnp.arange(g) != winner)
    ops = (fit, contender, winner, offsets, offsets_mask, eps_t, eps_theta)
    if SLOTS >= g:
        return _full(n_sub)(ops)
    idx = jnp.argsort(~others, stable=True)[:SLOTS]  # the contenders first, in index order
    gens = (idx[:, None] * n_sub + jnp.arange(n_sub)).reshape(-1)
    compact = _detect(*ops, jnp.repeat(others[idx], n_sub), gens)
    many = jnp.sum(others) > SLOTS
    full = sparse_cond(many, _full(n_sub), ops)
    return jax.tree.map(lambda a, b: jnp.where(many, a, b), full, compact)


@functools.cache
def _full(n_sub: int):
    """``detect_from`` on every generator, as a function of its operands (``sparse_cond``)."""

    def full(ops):
        fit, contender, winner = ops[:3]
        others = contender & (jnp.arange(contender.shape[0]) != winner)
        return _detect(*ops, jnp.repeat(others, n_sub), None)

    return full


def _detect(fit, contender, winner, offsets, offsets_mask, eps_t, eps_theta, source_ok, gens):
    """The verdict from the generators ``gens`` (indices into ``fit.gen``; None: all) whose
    source group contends (``source_ok``)."""
    d = fit.d
    offsets = offsets.astype(d.dtype)
    pick = (lambda a: a) if gens is None else (lambda a: a[gens])
    k_gen, ok_gen = pick(fit.k_gen), pick(fit.ok_gen)
    yaw_ok = jnp.all(jnp.where(contender, fit.dth <= eps_theta, True))
    gen_ok = source_ok & pick(fit.gen_len_ok)

    def coherent(ok):  # (C, G) residual tests -> (C,) every contender fits
        return jnp.all(jnp.where(contender[None], ok, True), axis=-1)

    def refine(k):  # least-squares period from integer multiples (C, G)
        kc = jnp.where(contender[None], k, 0.0)
        den = jnp.sum(kc * kc, axis=-1)
        return jnp.einsum("cg,gd->cd", kc, d) / jnp.maximum(den, 1.0)[:, None], den

    tau, den = refine(k_gen)
    # Validate against the layout: the nearest congruent-room offset must be within eps_t and
    # the anchors must also be coherent with that offset itself (this rejects generators that
    # only fit through loose integer multiples, e.g. 2/3 of the pitch).
    dist = jnp.linalg.norm(tau[:, None, :] - offsets[None], axis=-1)
    dist = jnp.where(offsets_mask[None], dist, jnp.inf)
    near = jnp.argmin(dist, axis=-1)
    room = offsets[near]
    layout_ok = jnp.min(dist, axis=-1) <= eps_t
    tau, den_room = refine(fit.k_off[near])
    valid = gen_ok & coherent(ok_gen) & layout_ok & coherent(fit.ok_off[near])
    valid = valid & (den > 0) & (den_room > 0)
    length = jnp.where(valid, jnp.linalg.norm(room, axis=-1), jnp.inf)
    best = jnp.argmin(length)
    ok = jnp.any(valid) & yaw_ok & (jnp.sum(contender) >= 2)
    t = tau[best]
    flip = (t[0] < -1e-6) | ((jnp.abs(t[0]) <= 1e-6) & (t[1] < 0))
    t = jnp.where(flip, -t, t)
    return ok, jnp.where(ok, t, jnp.zeros_like(t))


def detect(anchor, contender, winner, offsets, offsets_mask, eps_t, eps_theta, n_sub: int = 3):
    """Tests contender groups for one translational lattice.

    Args:
        anchor: ``(G, 3)`` group anchors.
        contender: ``(G,)`` bool groups taking part (the winner included).
        winner: ``()`` int32 index of the reference group.
        offsets: ``(P, 2)`` congruent-room offsets (both signs); offsets_mask: ``(P,)``.
        eps_t, eps_theta: lattice tolerances (m, rad).
        n_sub: static number of sub-harmonics tried per generator.

    Returns:
        ``(ok (), tau (2,))``: ``ok`` when at least two contenders form a coherent lattice whose
        period matches a room offset; ``tau`` is zero otherwise.
    """
    fit = prepare(anchor, winner, offsets, eps_t, n_sub)
    return detect_from(fit, contender, winner, offsets, offsets_mask, eps_t, eps_theta, n_sub)
