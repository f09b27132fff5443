"""Occupancy-aware verification score of a candidate pose ``Y = ^B T_S``.

With ``d(.)`` the floor plan's wall distance field (bilinear, m), ``in(.)`` its footprint mask
(bilinear in [0, 1]), submap points ``p_k`` (occupied) and free-space samples ``q_l`` taken along
each ray sensor origin -> point, stopping ``ray_stop`` metres short of the point:

    s(Y) = 1/|P| sum_k exp(-d(Y p_k)^2 / (2 sigma_occ^2))
         - lambda_free / |Q| sum_l max(exp(-d(Y q_l)^2 / (2 sigma_free^2)), 1 - in(Y q_l))

The first term (in [0, 1]) rewards occupied points that land on plan walls. The second (in
[0, lambda_free]) penalises space the LiDAR saw through that the plan calls wall or outside the
building. Points occupied in the submap but free in the plan (furniture, as-built additions)
only miss the reward; they are never penalised. Both per-cell terms are precomputed on the host
(``kernels``) and sampled at the nearest cell (STSL scores on a grid too). ``refine.py`` ascends
the occupancy term with a wider kernel (``sigma_refine``) sampled bilinearly
(``smooth_occupancy``); the free-space term is flat almost everywhere (its kernel lives inside
walls), so it contributes no useful gradient and is applied when re-scoring.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.floorplan.raster import bilinear, lookup

__all__ = ["free_samples", "kernels", "score", "smooth_occupancy"]


def free_samples(pts, org, ok, n_samples: int, stop: float):
    """Free-space samples along each ray, in the submap frame.

    Args:
        pts: ``(n, 2)`` points; ``org`` ``(n, 2)`` sensor origins; ``ok`` ``(n,)`` mask.
        n_samples: static samples per ray, at fractions ``k / n_samples`` of the free length.
        stop: metres kept free of samples before each point (range noise, grazing rays).

    Returns:
        ``(q (n * n_samples, 2), q_ok (n * n_samples,))``.
    """
    ray = pts - org
    length = jnp.sqrt(jnp.sum(ray * ray, -1))
    free_len = length - stop
    safe = jnp.where(length > 1e-6, length, 1.0)
    f = jnp.arange(n_samples, dtype=jnp.float32) / n_samples  # (M,)
    q = org[:, None, :] + (f[None, :, None] * (free_len / safe)[:, None, None]) * ray[:, None, :]
    q_ok = jnp.broadcast_to((ok & (free_len > 0))[:, None], q.shape[:2])
    return q.reshape(-1, 2), q_ok.reshape(-1)


def kernels(dist, inside, sigma_occ: float, sigma_free: float):
    """Host-side per-cell terms of the score, so a kernel sample is one lookup.

    Args:
        dist: ``(H, W)`` wall distance field (m); ``inside`` ``(H, W)`` footprint mask.

    Returns:
        ``(reward (H, W), penalty (H, W))`` float32: ``exp(-d^2 / 2 sigma_occ^2)`` and
        ``max(exp(-d^2 / 2 sigma_free^2), 1 - inside)``.
    """
    dist = np.asarray(dist, np.float64)
    reward = np.exp(-0.5 * (dist / sigma_occ) ** 2)
    penalty = np.maximum(np.exp(-0.5 * (dist / sigma_free) ** 2), 1.0 - np.asarray(inside, float))
    return reward.astype(np.float32), penalty.astype(np.float32)


def score(pose, pts, ok, q, q_ok, rasters, reward, penalty, lam):
    """Verification score of one pose (see module docstring), nearest-cell sampling.

    Args:
        pose: ``(3,)`` candidate ``^B T_S``.
        pts: ``(n, 2)`` occupied points (submap frame), ``ok`` their mask.
        q: ``(m, 2)`` free-space samples, ``q_ok`` their mask.
        rasters: ``Rasters`` (for the grid geometry).
        reward, penalty: ``(H, W)`` from ``kernels``.
        lam: free-space weight ``lambda_free``.

    Returns:
        Scalar score in ``[-lam, 1]``; 0 when there are no points.
    """
    occ = lookup(rasters, reward, se2.apply(pose, pts), 0.0)
    s_occ = jnp.sum(jnp.where(ok, occ, 0.0)) / jnp.maximum(jnp.sum(ok).astype(occ.dtype), 1.0)
    pen = lookup(rasters, penalty, se2.apply(pose, q), 1.0)
    s_free = jnp.sum(jnp.where(q_ok, pen, 0.0)) / jnp.maximum(jnp.sum(q_ok).astype(pen.dtype), 1.0)
    return s_occ - lam * s_free


def smooth_occupancy(pose, pts, ok, rasters, reward_smooth):
    """Occupancy term with bilinear sampling of a wider kernel: differentiable in ``pose``."""
    occ = bilinear(rasters, reward_smooth, se2.apply(pose, pts), 0.0)
    return jnp.sum(jnp.where(ok, occ, 0.0)) / jnp.maximum(jnp.sum(ok).astype(occ.dtype), 1.0)
