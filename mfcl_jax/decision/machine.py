"""A decision a robot can act on: a commit persists, tracks the anchor, and ends only on
evidence that contradicts it.

The per-prefix decision (``state.decide_prefix``) is a pure function of the windows seen so
far and may flip (COMMIT, then AMBIGUOUS when a new alias becomes feasible, then COMMIT...).
A robot cannot act on that, so the reported state is a small machine over the prefixes:

* before the first commit the reported decision is the per-prefix one (DEFER / AMBIGUOUS /
  COMMIT; the paper's reversible AMBIGUOUS -> COMMIT is kept);
* once committed to ``A``, the state stays COMMIT. The anchor is tracked under odometry drift:
  whenever the per-prefix winner ``T*`` lies within the grouping tolerances of ``A`` (the same
  place, re-estimated from the latest champions), ``A <- T*``; otherwise ``A`` is held;
* a commit is left only on contradicting evidence, reported as a typed reason:
  ``commit contradicted`` (another anchor, farther than the grouping tolerances from ``A``,
  has become decisive: the per-prefix decision commits to it) or ``commit infeasible`` (the
  trajectory mapped by the tracked anchor, this prefix's ``T*``, now fails the feasibility
  gate: the path walks through walls or out of the building; a held anchor that is no
  longer tracked is judged by the first rule). The state then becomes AMBIGUOUS
  (multimodal) resp. DEFER for that window, and the machine starts over from the next
  window (a new commit needs the per-prefix rules again).

``step`` is shared by the batch evaluator (``lax.scan`` over the prefixes) and the streaming
initializer (one step per window), so both report the same states.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import lattice
from mfcl_jax.decision.state import AMBIGUOUS, COMMIT, DEFER, Decisions

__all__ = ["Held", "CONTRADICTED", "INFEASIBLE", "initial", "step", "track"]

CONTRADICTED, INFEASIBLE = 9, 10  # keys of state.REASONS


@dataclass(frozen=True)
class Held:
    """The machine's memory: whether a commit is held and its (tracked) anchor."""

    committed: jax.Array  # () bool
    anchor: jax.Array  # (3,)


jax.tree_util.register_dataclass(Held, data_fields=["committed", "anchor"], meta_fields=[])


def initial(dtype=jnp.float32) -> Held:
    return Held(jnp.bool_(False), jnp.zeros((3,), dtype))


def step(held: Held, raw: Decisions, p, use_gate) -> tuple[Held, Decisions]:
    """One window.

    Args:
        held: the memory after the previous window.
        raw: this window's per-prefix decision (scalars).
        p: scalar ``DecisionParams`` (grouping tolerances, ``tau_c``).
        use_gate: ``()`` bool; without the gate a commit is never ``infeasible``.

    Returns:
        ``(held', reported decision)``.
    """
    dxy, dth = se2.distance_pair(raw.anchor, held.anchor)
    near = (dxy <= p.delta_xy) & (dth <= p.delta_theta)
    tracked = jnp.where(near, raw.anchor, held.anchor)
    # The tracked anchor is this prefix's T*, whose gate consistency the decision already has.
    infeasible = held.committed & near & use_gate & (raw.c_winner < p.tau_c)
    contradicted = held.committed & ~infeasible & (raw.state == COMMIT) & ~near
    keep = held.committed & ~infeasible & ~contradicted
    state = jnp.where(
        keep, COMMIT, jnp.where(infeasible, DEFER, jnp.where(contradicted, AMBIGUOUS, raw.state))
    ).astype(raw.state.dtype)
    kind = jnp.where(
        keep | infeasible, lattice.KIND_NONE, jnp.where(contradicted, lattice.MULTIMODAL, raw.kind)
    ).astype(raw.kind.dtype)
    reason = jnp.where(
        infeasible,
        INFEASIBLE,
        jnp.where(contradicted, CONTRADICTED, jnp.where(keep, 0, raw.reason)),
    ).astype(raw.reason.dtype)
    anchor = jnp.where(keep, tracked, raw.anchor)
    out = replace(
        raw,
        state=state,
        kind=kind,
        reason=reason,
        anchor=anchor,
        tau=jnp.where(kind == lattice.TRANSLATION, raw.tau, jnp.zeros_like(raw.tau)),
        alias_motion=jnp.where(
            kind == lattice.ROTATION, raw.alias_motion, jnp.zeros_like(raw.alias_motion)
        ),
    )
    new_commit = ~held.committed & (raw.state == COMMIT)
    committed = keep | new_commit
    held = Held(committed, jnp.where(keep, tracked, jnp.where(new_commit, raw.anchor, held.anchor)))
    return held, out


def track(raw: Decisions, p, use_gate) -> Decisions:
    """The machine over every prefix of one run (``raw`` leaves have leading axis ``K``)."""
    _, out = jax.lax.scan(lambda h, d: step(h, d, p, use_gate), initial(raw.anchor.dtype), raw)
    return out
