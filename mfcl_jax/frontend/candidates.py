"""What the front-end hands the decision layer: top-J scored candidate poses per submap."""

from __future__ import annotations

from dataclasses import dataclass

import jax
import numpy as np

__all__ = ["Candidates", "REASONS", "no_candidates"]


# Why a submap produced no candidates (Candidates.reason); the decision layer reports DEFER.
REASONS = {
    0: "ok",
    1: "empty submap",
    2: "too few points",
    3: "no features",
    4: "no walls in floor plan",
}


@dataclass(frozen=True)
class Candidates:
    """Front-end output: top-J scored candidates per submap.

    Attributes:
        pose: ``(N, J, 3)`` float32 ``Y_ij = ^B T_{S_i}``.
        score: ``(N, J)`` float32 verification score (higher is better).
        mask: ``(N, J)`` bool, valid candidates.
        reason: ``(N,)`` int32 key of ``REASONS`` (0 when candidates exist).
    """

    pose: jax.Array
    score: jax.Array
    mask: jax.Array
    reason: jax.Array


jax.tree_util.register_dataclass(
    Candidates, data_fields=["pose", "score", "mask", "reason"], meta_fields=[]
)


def no_candidates(n: int, J: int) -> Candidates:
    """``n`` submaps without candidates (host arrays, the front-end's shapes and dtypes)."""
    return Candidates(
        pose=np.zeros((n, J, 3), np.float32), score=np.full((n, J), -np.inf, np.float32),
        mask=np.zeros((n, J), bool), reason=np.zeros(n, np.int32),
    )  # fmt: skip
