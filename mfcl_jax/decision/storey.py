"""A commit on a place that stands for several congruent storeys names no storey.

A building's congruent storeys (the typical floors of a tower) are laid out once in the
stacked plan (``floorplan.storeys``): the scans cannot tell them apart, whatever the robot
does on them. A lane that would COMMIT with the robot on such a place reports
AMBIGUOUS(storey) instead, keeping its anchor (the place is known, the storey is not), and
holds no commit; the storeys that remain are listed on the host (``robot.records``).
Where the plan has one storey (``DecisionMaps.shared`` all False) nothing changes.
"""

from __future__ import annotations

from dataclasses import replace

import jax.numpy as jnp

from mfcl_jax.decision import gate, lattice
from mfcl_jax.decision.machine import Held
from mfcl_jax.decision.maps import DecisionMaps
from mfcl_jax.decision.outcome import AMBIGUOUS, COMMIT, Decision

__all__ = ["on_shared", "leave_shared"]


def on_shared(maps: DecisionMaps, anchors, traj, traj_mask, X) -> jnp.ndarray:
    """``(L,)`` bool: a lane's anchor puts the window's new keyframes or its last pose
    ``X`` in a room of a shared place (``DecisionMaps.shared``)."""
    pts = jnp.concatenate([traj, X[None].astype(traj.dtype)], axis=0)
    ok = jnp.concatenate([traj_mask, jnp.ones((1,), bool)])
    lab = gate.labels(maps, anchors, pts)  # (L, S + 1)
    room = (lab >= 0) & ok
    hit = maps.shared[jnp.where(room, lab, maps.shared.shape[0] - 1)]
    return jnp.any(room & hit, axis=-1)


def leave_shared(maps: DecisionMaps, held: Held, out: Decision, traj, traj_mask, X):
    """Lanes ``(L,)`` reporting COMMIT on a shared place report AMBIGUOUS(storey) and hold no
    commit; the others are unchanged."""
    d = on_shared(maps, out.anchor, traj, traj_mask, X) & (out.state == COMMIT)
    zero = jnp.zeros_like
    out = replace(
        out,
        state=jnp.where(d, AMBIGUOUS, out.state).astype(out.state.dtype),
        kind=jnp.where(d, lattice.STOREY, out.kind).astype(out.kind.dtype),
        reason=jnp.where(d, 0, out.reason).astype(out.reason.dtype),
        tau=jnp.where(d[:, None], zero(out.tau), out.tau),
        alias_motion=jnp.where(d[:, None], zero(out.alias_motion), out.alias_motion),
        competitor=jnp.where(d[:, None], zero(out.competitor), out.competitor),
        has_competitor=out.has_competitor & ~d,
    )
    return Held(held.committed & ~d, held.anchor), out
