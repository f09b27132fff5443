"""Candidate anchoring ``H_ij = Y_ij X_i^-1``.

Every candidate of submap ``i`` proposes ``Y_ij = ^B T_{S_i}``; the odometry gives
``X_i = ^L T_{S_i}``. Chaining through ``S_i`` gives one estimate ``^B T_L`` per candidate, so
candidates of different submaps become comparable. Only ``Y X^-1`` cancels the submap frame;
``X^-1 Y`` is a different (wrong) quantity whenever ``X`` rotates.

Non-finite candidates are rejected here, at the edge of the decision layer: they are masked
out and counted, never allowed to reach a mean or a distance.
"""

from __future__ import annotations

import jax.numpy as jnp

from mfcl_jax import se2

__all__ = ["candidate_anchors", "sanitize"]


def sanitize(pose, score, mask):
    """Masks out candidates with a non-finite pose or score.

    Args:
        pose: ``(..., J, 3)`` candidate poses.
        score: ``(..., J)`` scores.
        mask: ``(..., J)`` bool validity.

    Returns:
        ``(pose, score, mask, n_bad)``: rejected entries are zeroed (so no NaN can leak through
        a masked reduction), ``mask`` excludes them, ``n_bad (...)`` int32 counts them.
    """
    pose, score, mask = jnp.asarray(pose), jnp.asarray(score), jnp.asarray(mask, bool)
    finite = jnp.all(jnp.isfinite(pose), axis=-1) & jnp.isfinite(score)
    bad = mask & ~finite
    keep = mask & finite
    pose = jnp.where(keep[..., None], pose, jnp.zeros_like(pose))
    score = jnp.where(keep, score, jnp.zeros_like(score))
    return pose, score, keep, jnp.sum(bad, axis=-1).astype(jnp.int32)


def candidate_anchors(Y, X):
    """Anchors ``H = Y X^-1`` of every candidate.

    Args:
        Y: ``(N, J, 3)`` candidate submap poses in the floor plan, ``^B T_{S_i}``.
        X: ``(N, 3)`` submap poses in odometry, ``^L T_{S_i}``.

    Returns:
        ``(N, J, 3)`` anchors ``^B T_L``.
    """
    return se2.anchor(jnp.asarray(Y), jnp.asarray(X)[..., None, :])
