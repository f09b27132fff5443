"""Continuous refinement of candidate poses on the smooth verification score (optax adam).

The Hough cell (``cell`` m, 1 deg) bounds the accuracy of a voted pose; gradient ascent on the
bilinear occupancy kernel (``verify.smooth_occupancy``, sigma ``sigma_refine``) removes that
bound. The heading is optimised in metres of arc at
``yaw_lever`` m (``theta * yaw_lever``) so adam's per-coordinate step sizes are comparable.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax

from mfcl_jax import se2
from mfcl_jax.frontend import verify

__all__ = ["refine"]


def refine(poses, pts, ok, rasters, reward_smooth, p):
    """Refines ``(J, 3)`` poses of one submap; returns refined ``(J, 3)`` poses.

    Args:
        poses: ``(J, 3)`` initial candidates.
        pts, ok: ``(n, 2)`` occupied points and mask (submap frame).
        rasters: floor-plan ``Rasters`` (grid geometry).
        reward_smooth: ``(H, W)`` occupancy kernel at ``sigma_refine``.
        p: ``FrontendParams`` (``refine_steps``, ``refine_lr``, ``sigma_refine``...).
    """
    scale = jnp.asarray([1.0, 1.0, p.yaw_lever])
    opt = optax.adam(optax.cosine_decay_schedule(p.refine_lr, p.refine_steps, alpha=0.1))

    def loss(z, pose0):
        pose = pose0 + z / scale
        return -verify.smooth_occupancy(pose, pts, ok, rasters, reward_smooth)

    grad = jax.grad(loss)

    def one(pose0):
        z0 = jnp.zeros(3)

        def step(carry, _):
            z, st = carry
            g = grad(z, pose0)
            g = jnp.where(jnp.isfinite(g), g, 0.0)
            # optax mixes python floats and int32 step counts: allow standard promotion
            # here even when the caller runs with strict promotion.
            with jax.numpy_dtype_promotion("standard"):
                upd, st = opt.update(g, st, z)
            return (optax.apply_updates(z, upd), st), None

        with jax.numpy_dtype_promotion("standard"):
            st0 = opt.init(z0)
        (z, _), _ = jax.lax.scan(step, (z0, st0), None, length=p.refine_steps)
        pose = pose0 + z / scale
        return jnp.concatenate([pose[:2], se2.wrap(pose[2:])])

    return jax.vmap(one)(poses)
