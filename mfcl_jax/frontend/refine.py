"""Continuous refinement of candidate poses: reweighted Gauss-Newton on the verification score.

Maximising the occupancy term of ``verify.score``, ``mean_k exp(-d(Y p_k)^2 / 2 sigma^2)`` with
``d`` the bilinear signed wall-surface distance, is a robust (Welsch) least-squares problem in
the residuals ``d(Y p_k)``: iteratively reweighted Gauss-Newton with weights
``exp(-d^2 / 2 sigma^2)`` ascends exactly that objective, and converges in a handful of steps
where first-order ascent needs tens. ``sigma`` shrinks geometrically from ``sigma_refine``
(capture range of a Hough peak, ~0.5 m / 2 deg) to ``sigma_occ`` (the scoring width) over the
first half of the steps and stays there, so the final steps optimise the very score that later
decides whether the refined pose is kept. Steps are damped (Levenberg) and clipped to
``refine_max_step`` metres and ``10 x refine_max_step`` degrees; a direction that no wall
constrains (a corridor's axis) stays put instead of drifting.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.frontend import verify

__all__ = ["refine", "sigma_schedule"]


def sigma_schedule(p) -> np.ndarray:
    """``(refine_steps,)`` kernel widths: geometric ``sigma_refine -> sigma_occ``, then flat."""
    n = p.refine_steps
    k = max(1, n // 2)
    s = np.geomspace(p.sigma_refine, p.sigma_occ, k) if k > 1 else np.array([p.sigma_occ])
    return np.concatenate([s, np.full(n - k, p.sigma_occ)]).astype(np.float32)


def refine(poses, pts, ok, feats, p):
    """Refines ``(J, 3)`` poses of one submap; returns refined ``(J, 3)`` poses.

    Args:
        poses: ``(J, 3)`` initial candidates.
        pts, ok: ``(n, 2)`` occupied points and mask (submap frame).
        feats: ``FloorplanFeatures`` (``sdf4`` and the raster geometry).
        p: ``FrontendParams`` (``refine_steps``, ``sigma_refine``, ``sigma_occ``,
            ``refine_max_step``).
    """
    r = feats.rasters
    okf = ok.astype(jnp.float32)
    max_xy = p.refine_max_step
    max_th = np.radians(10.0 * p.refine_max_step)

    def step(pose, sigma):
        c, s = jnp.cos(pose[2]), jnp.sin(pose[2])
        w_pts = se2.apply(pose, pts)
        d, g = verify.sample(r.origin, r.res, feats.sdf4, w_pts, verify.FAR, grad=True)
        # d(world point)/d(theta) = R'(theta) p
        dth = jnp.stack([-s * pts[:, 0] - c * pts[:, 1], c * pts[:, 0] - s * pts[:, 1]], -1)
        jac = jnp.concatenate([g, jnp.sum(g * dth, -1, keepdims=True)], -1)  # (n, 3)
        wt = okf * jnp.exp(-0.5 * (d / sigma) ** 2)
        h = jnp.einsum("n,ni,nj->ij", wt, jac, jac)
        b = jnp.einsum("n,ni,n->i", wt, jac, d)
        lam = 1e-3 * jnp.trace(h) / 3.0 + 1e-6
        delta = -jnp.linalg.solve(h + lam * jnp.eye(3, dtype=h.dtype), b)
        delta = jnp.where(jnp.all(jnp.isfinite(delta)), delta, 0.0)
        nxy = jnp.sqrt(jnp.sum(delta[:2] ** 2))
        delta = delta.at[:2].multiply(jnp.minimum(1.0, max_xy / jnp.maximum(nxy, 1e-9)))
        delta = delta.at[2].set(jnp.clip(delta[2], -max_th, max_th))
        new = pose + delta
        return jnp.concatenate([new[:2], se2.wrap(new[2:])]), None

    sig = jnp.asarray(sigma_schedule(p))

    def one(pose0):
        pose, _ = jax.lax.scan(step, pose0, sig)
        return pose

    return jax.vmap(one)(poses)
