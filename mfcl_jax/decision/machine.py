"""A decision a robot can act on: a commit persists, tracks the anchor, and ends only on
evidence that contradicts it.

The rule at each window (``rule.finish``) is a pure function of the windows seen so
far and may flip (COMMIT, then AMBIGUOUS when a new alias becomes feasible, then COMMIT...).
A robot cannot act on that, so the reported state is a small machine over the prefixes:

* before the first commit the reported decision is the per-prefix one (DEFER / AMBIGUOUS /
  COMMIT; the paper's reversible AMBIGUOUS -> COMMIT is kept);
* once committed to ``A``, the state stays COMMIT. The anchor is tracked under odometry drift:
  its target is the newest window's best candidate that places the robot within ``TRACK``
  (0.5 m, 3 deg) of where ``A`` does (the front-end's registration of the latest scans: the
  most current estimate); failing one, the per-prefix winner ``T*`` when it places the robot
  within ``TRACK`` of where ``A`` does (the same place, re-estimated from recent champions);
  failing both, ``A`` itself. ``A`` moves half-way to its target (``se2.mean_pose`` of the
  two). Half-way, because one window's registration is noisy: in a hall whose walls pin one
  direction only, taking each newest candidate outright let the anchor random-walk along the
  free direction (1.1-1.5 m off within a few windows: two hall runs of the benchmark at the
  (2, 1) floors); half-way makes the tracking error a damped average of the recent
  registrations (variance a third of one window's) and still follows drift, one window's
  drift behind. ``T*`` is held to ``TRACK`` too: within the looser grouping tolerances it
  turned a committed anchor 5 deg on a real log (freiburg, (2, 1) floors);
* a commit is left only on contradicting evidence, reported as a typed reason:
  ``commit contradicted`` (another anchor, farther than the grouping tolerances from ``A``,
  has become decisive: the per-prefix decision commits to it) or ``commit infeasible`` (the
  trajectory mapped by the tracked anchor, this prefix's ``T*``, now fails the feasibility
  gate: the path walks through walls or out of the building; a held anchor that is no
  longer tracked is judged by the first rule) or ``commit stale`` (the newest window's best
  registration places the robot at the commit's place, within the grouping tolerances, but
  farther than ``TRACK`` from where the held anchor does: the odometry has drifted faster
  than the tracking follows, and the held pose is no longer what the scans say; measured on
  the raw Intel bag, whose LiDAR odometry turned the true anchor by 1.5-2 deg a window: the
  tracked commit lagged and was 6.7 deg off four windows after a right commit). The state
  then becomes AMBIGUOUS (multimodal) resp. DEFER for that window, and the machine starts
  over from the next window (a new commit needs the per-prefix rules again).

``step`` is one transition; the layer (``decision.layer.update``) takes it once per window
and lane, for the robot and the batch alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import lattice
from mfcl_jax.decision.outcome import AMBIGUOUS, COMMIT, DEFER, Decision

__all__ = [
    "Held",
    "CONTRADICTED",
    "INFEASIBLE",
    "STALE",
    "DRIFTED",
    "UNSUPPORTED",
    "initial",
    "step",
    "leave_drifted",
]

CONTRADICTED, INFEASIBLE, STALE, DRIFTED, UNSUPPORTED = 9, 10, 13, 14, 15  # outcome.REASONS
TRACK = (0.5, math.radians(3.0))  # a newest candidate this close to the held anchor tracks it


@dataclass(frozen=True)
class Held:
    """The machine's memory: whether a commit is held and its (tracked) anchor."""

    committed: jax.Array  # () bool
    anchor: jax.Array  # (3,)


jax.tree_util.register_dataclass(Held, data_fields=["committed", "anchor"], meta_fields=[])


def initial(dtype=jnp.float32) -> Held:
    return Held(jnp.bool_(False), jnp.zeros((3,), dtype))


def _newest(held_anchor, newest):
    """The newest window's best candidate that places the robot within ``TRACK`` of where
    the held anchor does: ``(anchor (3,), found ())``."""
    H, score, mask, x = newest
    here = se2.compose(held_anchor, x)
    dxy, dth = se2.distance_pair(se2.compose(H, x[None]), here[None])
    close = mask & (dxy <= TRACK[0]) & (dth <= TRACK[1])
    j = jnp.argmax(jnp.where(close, score, -jnp.inf))
    return H[j], jnp.any(close)


def _stale(held_anchor, newest, p):
    """The newest window's best registration places the robot at the held commit's place
    (within the grouping tolerances) but farther than ``TRACK`` from where the commit does."""
    H, score, mask, x = newest
    j = jnp.argmax(jnp.where(mask, score, -jnp.inf))
    dxy, dth = se2.distance_pair(se2.compose(H[j], x), se2.compose(held_anchor, x))
    same = (dxy <= p.delta_xy) & (dth <= p.delta_theta)
    return jnp.any(mask) & same & ((dxy > TRACK[0]) | (dth > TRACK[1]))


def step(held: Held, raw: Decision, newest, p, use_gate) -> tuple[Held, Decision]:
    """One window.

    Args:
        held: the memory after the previous window.
        raw: this window's per-prefix decision (scalars).
        newest: ``(H (J, 3), score (J,), mask (J,), x (3,))`` the newest window's candidate
            anchors and its odometry pose, for tracking.
        p: scalar ``DecisionParams`` (grouping tolerances, ``tau_c``).
        use_gate: ``()`` bool; without the gate a commit is never ``infeasible``.

    Returns:
        ``(held', reported decision)``.
    """
    dxy, dth = se2.distance_pair(raw.anchor, held.anchor)
    near = (dxy <= p.delta_xy) & (dth <= p.delta_theta)
    cand, found = _newest(held.anchor, newest)
    x = newest[3]
    txy, tth = se2.distance_pair(se2.compose(raw.anchor, x), se2.compose(held.anchor, x))
    same = near & (txy <= TRACK[0]) & (tth <= TRACK[1])
    target = jnp.where(found, cand, jnp.where(same, raw.anchor, held.anchor))
    tracked = se2.mean_pose(jnp.stack([held.anchor, target]), axis=0)
    # The tracked anchor is this prefix's T*, whose gate consistency the decision already has.
    infeasible = held.committed & near & use_gate & (raw.c_winner < p.tau_c)
    contradicted = held.committed & ~infeasible & (raw.state == COMMIT) & ~near
    stale = held.committed & ~infeasible & ~contradicted & _stale(held.anchor, newest, p)
    keep = held.committed & ~infeasible & ~contradicted & ~stale
    deferred = infeasible | stale  # both leave the commit as DEFER
    state = jnp.where(
        keep, COMMIT, jnp.where(deferred, DEFER, jnp.where(contradicted, AMBIGUOUS, raw.state))
    ).astype(raw.state.dtype)
    kind = jnp.where(
        keep | deferred, lattice.KIND_NONE, jnp.where(contradicted, lattice.MULTIMODAL, raw.kind)
    ).astype(raw.kind.dtype)
    reason = jnp.where(
        deferred,
        jnp.where(stale, STALE, INFEASIBLE),
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
        # a contradicted commit's competitor is the commit itself; a held or left one has none
        competitor=jnp.where(
            contradicted,
            held.anchor,
            jnp.where(keep | deferred, jnp.zeros_like(raw.competitor), raw.competitor),
        ),
        has_competitor=contradicted | (raw.has_competitor & ~keep & ~deferred),
    )
    new_commit = ~held.committed & (raw.state == COMMIT)
    committed = keep | new_commit
    held = Held(committed, jnp.where(keep, tracked, jnp.where(new_commit, raw.anchor, held.anchor)))
    return held, out


def leave_drifted(held: Held, out: Decision, verdict) -> tuple[Held, Decision]:
    """Lanes ``(L,)`` whose reported COMMIT the window's last scan does not support
    (``drift.verdict``: ``DRIFTED`` or ``UNSUPPORTED``, else 0) report DEFER with that reason
    instead and hold no commit afterwards; the others are unchanged."""
    d = (verdict != 0) & (out.state == COMMIT)
    zero = jnp.zeros_like
    out = replace(
        out,
        state=jnp.where(d, DEFER, out.state).astype(out.state.dtype),
        kind=jnp.where(d, lattice.KIND_NONE, out.kind).astype(out.kind.dtype),
        reason=jnp.where(d, verdict, out.reason).astype(out.reason.dtype),
        tau=jnp.where(d[:, None], zero(out.tau), out.tau),
        alias_motion=jnp.where(d[:, None], zero(out.alias_motion), out.alias_motion),
        competitor=jnp.where(d[:, None], zero(out.competitor), out.competitor),
        has_competitor=out.has_competitor & ~d,
    )
    return Held(held.committed & ~d, held.anchor), out
