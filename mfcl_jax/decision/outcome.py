"""What the decision layer says after a window: the ``Decision`` pytree and its codes.

One ``Decision`` per lane and window; leaves carry any leading axes (``(L,)`` from one
``update``, ``(R, K, L)`` from a batch). Host tables and JSON lines are made from it at the
edge (``decision.frame``, ``io.decisions``), never inside the kernels.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax

__all__ = ["DEFER", "AMBIGUOUS", "COMMIT", "STATE_NAMES", "REASONS", "Decision"]

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
    14: "commit drifted",
    15: "commit unsupported",
}


@dataclass(frozen=True)
class Decision:
    """One decision (scalar leaves per lane and window)."""

    state: jax.Array  # int32 DEFER/AMBIGUOUS/COMMIT
    kind: jax.Array  # int32 lattice.KIND_*
    anchor: jax.Array  # (3,) T* (ours; the tracked commit anchor when held) or the policy's pick
    tau: jax.Array  # (2,) zero unless kind == translation
    b1: jax.Array  # int32 scan-disjoint support of the winner
    b2: jax.Array  # int32 of the runner-up (groups the certification ruled out not counted)
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
    alias_motion: jax.Array  # (3,) self-motion g of a rotational alias; zero unless rotation
    # (3,) the strongest competing explanation of an AMBIGUOUS decision: the competitor the
    # certification did not rule out (the one with the smallest largest advantage), else the
    # runner-up consensus group counted in B2 (a held commit that a new winner contradicts,
    # in ``machine``); zero when ``has_competitor`` is false
    competitor: jax.Array
    has_competitor: jax.Array  # bool
    n_live: jax.Array  # int32 competitors not ruled out (0 unless certification blocked)
    certified: jax.Array  # bool: the certification ran at this window (B2 counts its verdicts)
    searched: jax.Array  # bool: the rival search ran at this window
    n_rejected: jax.Array  # int32 non-finite candidates rejected so far
    dropped: jax.Array  # int32 windows that have left the layer's history (its capacity)
    # the uniqueness test's log-likelihood ratio of the path, best placement against the best
    # other one (``uniqueness``; NaN where it did not run, +inf with no other placement)
    llr: jax.Array
    # (3,) the uniqueness test's best placement A* of the path (the anchor it commits to where
    # it holds; zero where it did not run): what its ratio is judged by
    test_anchor: jax.Array


jax.tree_util.register_dataclass(
    Decision, data_fields=list(Decision.__dataclass_fields__), meta_fields=[]
)
