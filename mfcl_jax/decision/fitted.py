"""Every explanation scored at its best fit to each window (the certification's scoring).

The score's kernel is sharp (``cert_sigma``, 7 cm), so a pose a few
centimetres off a window loses much of its score. ``T*`` is an average of recent champions
and each window's anchor moves with the odometry's drift, while a runner-up candidate or a
rival of the global search is fitted to its own window or path: compared as they come, the
less-fitted explanation loses by its misfit, not by the walls. So every explanation
(``T*`` included) is scored in every window at its best fit within a few centimetres and
tenths of a degree (``REFINE``: two rounds of steps along each axis, 13 poses), the same for all.
Measured before this rule: a half-turn rival of a symmetric building was "contradicted" by
one window (advantage 0.20) and "favoured" by another (-0.08), both by misfit; fitted, it
ties in both (0.05, 0.01). Each ray also carries ``FREE_PER_RAY`` free-space samples (at 0,
1/4, 1/2 and 3/4 of its free length), so an explanation under which the robot saw through
a plan wall is penalised, not only one that puts the sensor in a wall.

``window_scores`` also returns, at the fitted poses, each window's score per contiguous block
of its points and the free-space term alone (window and blocks), which ``certify`` reads.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.frontend import verify

__all__ = ["REFINE", "FREE_PER_RAY", "window_scores"]

# Every explanation is scored at its best fit to each window: two rounds of one step either way
# along x, y and the heading (6 cm / 0.6 deg, then 2 cm / 0.2 deg; module docstring).
REFINE = ((0.06, math.radians(0.6)), (0.02, math.radians(0.2)))
FREE_PER_RAY = 4  # free-space samples per ray (a ray through a plan wall is penalised)


def _moves(steps) -> tuple:
    """The refinement as a table: per step the axis, the signed step and whether it starts a
    new axis (both signs of an axis are tried from the same centre)."""
    rows = [(axis, sign * st, sign > 0)
            for st_xy, st_th in steps
            for axis, st in ((0, st_xy), (1, st_xy), (2, st_th))
            for sign in (1.0, -1.0)]  # fmt: skip
    axis, step, first = zip(*rows, strict=True) if rows else ((), (), ())
    return (jnp.asarray(axis, jnp.int32), jnp.asarray(step, jnp.float32),
            jnp.asarray(first, bool))  # fmt: skip


def window_scores(poses, pts, org, pmask, maps, sigma, lam, n_free: int, steps=REFINE,
                  n_blocks: int = 4):  # fmt: skip
    """Verification score of each window (rows) under each pose ``(W, C, 3)``, each pose at
    its best fit: per round of ``steps`` (``(step_xy, step_theta)``), a step either way along
    x, y and the heading in turn (in the window's frame), each kept where it scores higher.

    Returns:
        ``(scores (W, C), block_scores (W, C, n_blocks), free (W, C), free_blocks (W, C,
        n_blocks))``: the rest at the fitted poses: per contiguous block of each window's
        points (``verify.block_scores``), and the free-space term alone (``-lam`` times the
        mean penalty of the rays' free samples) of the window and of each block.
    """
    axis, step, first = _moves(steps)

    def one_window(pose_c, p, o, m):
        q, q_ok = verify.free_samples(p, o, m, n_free, 0.3)

        def one(y):
            return verify.score_fields(
                y, p, m, q, q_ok, maps.origin, maps.res, maps.sdf4, maps.pen4, sigma, lam
            )

        def blocks(y):
            hit, pen = verify.point_terms(
                y, p, q, maps.origin, maps.res, maps.sdf4, maps.pen4, sigma
            )
            hb, pb = verify.block_terms(hit, pen, m, q_ok, n_blocks)
            _, pw = verify.term_means(hit, pen, m, q_ok)
            # the score per block, and the free-space term alone (window, then blocks)
            return hb - lam * pb, -lam * pw, -lam * pb

        def body(carry, mv):
            y, best, centre = carry
            ax, st, new_axis = mv
            centre = jnp.where(new_axis, y, centre)
            move = jnp.zeros(3, y.dtype).at[ax].set(st)
            cand = se2.compose(centre, move[None])
            sc = jax.vmap(one)(cand)
            better = sc > best
            return (jnp.where(better[:, None], cand, y), jnp.where(better, sc, best), centre), None

        y = pose_c  # (C, 3)
        (y, best, _), _ = jax.lax.scan(body, (y, jax.vmap(one)(y), y), (axis, step, first),
                                       length=len(steps) * 6)  # fmt: skip
        return (best, *jax.vmap(blocks)(y))

    return jax.vmap(one_window)(poses, pts, org, pmask)
