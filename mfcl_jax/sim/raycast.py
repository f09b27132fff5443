"""Planar 360-degree LiDAR: ray casting against line segments.

The sensor is a Livox Mid-360 sliced to a horizontal 2D ring. Facts of that sensor that set the
defaults: 360 deg horizontal field of view, 40 m range at 10 % reflectivity (70 m at 80 %),
0.1 m minimum range, about 2 cm range precision (1 sigma at 10 m). A 2D slice keeps one ring;
720 beams (0.5 deg) puts returns about 9 cm apart at 10 m, close to the 0.10 m voxel and raster
resolution used downstream, so finer rings would add cost and no information. A few per cent of
returns are lost (dark or glossy surfaces, glass): ``dropout = 0.02``.

A beam that hits nothing within ``max_range`` (or hits closer than ``min_range``, or drops out)
returns NaN: it is not a point. Treating misses as max-range points would invent walls.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["LidarParams", "beam_angles", "cast", "cast_kernel", "scan_points"]


@dataclass(frozen=True)
class LidarParams:
    """Planar LiDAR model (defaults: a Livox Mid-360 ring, see the module docstring).

    Attributes:
        n_beams: beams over 360 deg, evenly spaced from 0 rad (static: fixes shapes).
        min_range: returns closer than this are invalid (m).
        max_range: no return beyond this (m).
        sigma: Gaussian range noise (m).
        dropout: probability that a beam returns nothing.
    """

    n_beams: int = 720
    min_range: float = 0.1
    max_range: float = 40.0
    sigma: float = 0.02
    dropout: float = 0.02

    def __post_init__(self):
        if not (isinstance(self.n_beams, int | np.integer) and self.n_beams > 0):
            raise ValueError(f"LidarParams.n_beams must be a positive int, got {self.n_beams!r}")
        if not 0 <= self.min_range < self.max_range:
            raise ValueError(
                f"LidarParams needs 0 <= min_range < max_range, got "
                f"min_range={self.min_range!r}, max_range={self.max_range!r}"
            )
        if not self.sigma >= 0:
            raise ValueError(f"LidarParams.sigma must be >= 0, got {self.sigma!r}")
        if not 0 <= self.dropout < 1:
            raise ValueError(f"LidarParams.dropout must be in [0, 1), got {self.dropout!r}")


def beam_angles(n_beams: int) -> jax.Array:
    """Beam directions in the sensor frame ``(n_beams,)`` (rad)."""
    return jnp.arange(n_beams, dtype=jnp.float32) * (2 * jnp.pi / n_beams)


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _first_hit(pose, segments, seg_valid, dirs_local):
    """Distance to the nearest segment along each beam of one pose; inf where none."""
    c, s = jnp.cos(pose[2]), jnp.sin(pose[2])
    d = jnp.stack(
        [c * dirs_local[:, 0] - s * dirs_local[:, 1], s * dirs_local[:, 0] + c * dirs_local[:, 1]],
        axis=-1,
    )  # (B, 2)
    a = segments[:, 0]  # (M, 2)
    e = segments[:, 1] - a
    w = a - pose[:2]
    # Solve o + t d = a + u e:  t = (w x e) / (d x e),  u = (w x d) / (d x e).
    den = _cross(d[:, None, :], e[None, :, :])  # (B, M)
    ok = (jnp.abs(den) > 1e-9) & seg_valid[None, :]
    safe = jnp.where(ok, den, 1.0)
    t = _cross(w, e)[None, :] / safe
    u = _cross(w[None, :, :], d[:, None, :]) / safe
    # A little slack on u closes the cracks where two segments meet (a beam through a shared
    # end point must not slip between them through rounding).
    hit = ok & (t > 0) & (u >= -1e-5) & (u <= 1 + 1e-5)
    return jnp.min(jnp.where(hit, t, jnp.inf), axis=1)


def cast_kernel(
    poses, segments, seg_valid, keys, n_beams, min_range, max_range, sigma, dropout, chunk=32
):
    """Ray casts many poses (pure; ``n_beams`` and ``chunk`` must be static under jit).

    Args:
        poses: ``(S, 3)`` sensor poses in the segments' frame.
        segments: ``(M, 2, 2)`` surfaces.
        seg_valid: ``(M,)`` bool; padded segments are False.
        keys: ``(S, 2)`` uint32 PRNG keys, one per pose (noise and dropout).
        n_beams: beams per scan.
        min_range, max_range, sigma, dropout: see ``LidarParams`` (traced scalars).
        chunk: poses per vectorised step (bounds memory at chunk * n_beams * M).

    Returns:
        ``(S, n_beams)`` float32 ranges, NaN where invalid.
    """
    ang = beam_angles(n_beams)
    dirs = jnp.stack([jnp.cos(ang), jnp.sin(ang)], axis=-1)

    def one(args):
        pose, key = args
        r = _first_hit(pose, segments, seg_valid, dirs)
        k_noise, k_drop = jax.random.split(key)
        r_noisy = r + sigma * jax.random.normal(k_noise, r.shape, r.dtype)
        kept = jax.random.uniform(k_drop, r.shape) >= dropout
        valid = jnp.isfinite(r) & (r <= max_range) & (r_noisy >= min_range) & kept
        return jnp.where(valid, r_noisy, jnp.nan)

    return jax.lax.map(one, (poses, keys), batch_size=chunk)


@partial(jax.jit, static_argnames=("n_beams",))
def _cast_jit(poses, segments, seg_valid, keys, n_beams, min_range, max_range, sigma, dropout):
    return cast_kernel(
        poses, segments, seg_valid, keys, n_beams, min_range, max_range, sigma, dropout
    )


def cast(poses, segments, params: LidarParams = LidarParams(), key=None, seg_valid=None):
    """Simulated 2D scans at many poses (one jitted, vmapped call).

    Args:
        poses: ``(S, 3)`` sensor poses (x, y, theta) in the frame of ``segments``.
        segments: ``(M, 2, 2)`` surfaces (wall faces and clutter).
        params: LiDAR model.
        key: one PRNG key (split into one per pose) or ``(S, 2)`` keys, one per pose (a pose's
            scan then depends only on its own key, whatever else is in the batch).
        seg_valid: optional ``(M,)`` bool mask of real segments (for padded segment arrays).

    Returns:
        ``(S, n_beams)`` float32 ranges; beam ``b`` points at ``2 pi b / n_beams`` in the sensor
        frame; NaN marks no return.
    """
    poses = jnp.asarray(poses, jnp.float32).reshape(-1, 3)
    segments = jnp.asarray(segments, jnp.float32)
    if segments.ndim != 3 or segments.shape[1:] != (2, 2):
        raise ValueError(f"segments must be (M, 2, 2), got shape {segments.shape}")
    if not bool(jnp.all(jnp.isfinite(poses))):
        raise ValueError("cast: poses contain NaN or inf")
    seg_valid = (
        jnp.ones(segments.shape[0], bool) if seg_valid is None else jnp.asarray(seg_valid, bool)
    )
    key = jax.random.PRNGKey(0) if key is None else jnp.asarray(key)
    keys = key if key.ndim == 2 else jax.random.split(key, poses.shape[0])
    if keys.shape[0] != poses.shape[0]:
        raise ValueError(f"cast: {keys.shape[0]} keys for {poses.shape[0]} poses")
    return _cast_jit(
        poses,
        segments,
        seg_valid,
        keys,
        int(params.n_beams),
        jnp.float32(params.min_range),
        jnp.float32(params.max_range),
        jnp.float32(params.sigma),
        jnp.float32(params.dropout),
    )


def scan_points(ranges, n_beams: int | None = None):
    """Points in the sensor frame from ranges ``(..., B)`` -> ``(..., B, 2)``, NaN if invalid."""
    ranges = jnp.asarray(ranges)
    ang = beam_angles(ranges.shape[-1] if n_beams is None else n_beams)
    return ranges[..., None] * jnp.stack([jnp.cos(ang), jnp.sin(ang)], axis=-1)
