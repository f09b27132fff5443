"""SE(2) algebra on stacked poses.

A pose is one array type throughout the project: a float array of shape ``(*, 3)`` holding
``(x, y, theta)`` with ``theta`` in radians, wrapped to ``[-pi, pi]``. Every function broadcasts
over leading axes, is pure, and is safe under ``jit``/``vmap``. Accepts NumPy or JAX arrays and
returns JAX arrays.

Conventions: ``compose(a, b)`` is the matrix product ``a @ b`` (apply ``b`` first, then ``a``),
so with ``Y = ^B T_S`` and ``X = ^L T_S`` the anchor is ``anchor(Y, X) = Y X^-1 = ^B T_L``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

__all__ = [
    "wrap",
    "angle_diff",
    "make",
    "identity",
    "compose",
    "inverse",
    "between",
    "anchor",
    "apply",
    "rotate",
    "to_matrix",
    "from_matrix",
    "circular_mean",
    "mean_pose",
    "distance_pair",
    "compose_host",
    "inverse_host",
    "wrap_host",
]


def wrap(theta):
    """Wraps angles to ``[-pi, pi]``.

    Args:
        theta: angles in radians, any shape.

    Returns:
        The same angles wrapped, same shape.
    """
    theta = jnp.asarray(theta)
    # atan2 of (sin, cos) is exact to rounding and has no branch; +-pi are the same angle and
    # either may come back for inputs within float rounding of the cut.
    return jnp.arctan2(jnp.sin(theta), jnp.cos(theta))


def angle_diff(a, b):
    """Wrapped difference ``a - b`` in ``[-pi, pi]``."""
    return wrap(jnp.asarray(a) - jnp.asarray(b))


def make(x, y, theta):
    """Stacks components into poses ``(*, 3)``; the angle is wrapped."""
    x, y, theta = jnp.broadcast_arrays(jnp.asarray(x), jnp.asarray(y), jnp.asarray(theta))
    return jnp.stack([x, y, wrap(theta)], axis=-1)


def identity(shape=(), dtype=jnp.float32):
    """Identity poses of leading shape ``shape``."""
    return jnp.zeros((*shape, 3), dtype=dtype)


def rotate(theta, v):
    """Rotates 2-vectors ``v (*, 2)`` by angles ``theta (*)``."""
    c, s = jnp.cos(theta), jnp.sin(theta)
    vx, vy = v[..., 0], v[..., 1]
    return jnp.stack([c * vx - s * vy, s * vx + c * vy], axis=-1)


def compose(a, b):
    """Group product ``a b`` of poses ``(*, 3)`` (broadcasting)."""
    a, b = jnp.asarray(a), jnp.asarray(b)
    t = a[..., :2] + rotate(a[..., 2], b[..., :2])
    return jnp.concatenate([t, wrap(a[..., 2] + b[..., 2])[..., None]], axis=-1)


def inverse(a):
    """Group inverse of poses ``(*, 3)``."""
    a = jnp.asarray(a)
    t = -rotate(-a[..., 2], a[..., :2])
    return jnp.concatenate([t, wrap(-a[..., 2])[..., None]], axis=-1)


def between(a, b):
    """Relative pose ``a^-1 b``."""
    return compose(inverse(a), b)


def anchor(y, x):
    """Candidate anchor ``H = Y X^-1``.

    Args:
        y: ``^B T_S`` candidate submap poses in the floor plan, ``(*, 3)``.
        x: ``^L T_S`` submap poses from odometry, ``(*, 3)`` (broadcasts against ``y``).

    Returns:
        ``^B T_L``, ``(*, 3)``. The order matters: only ``Y X^-1`` cancels the submap frame.
    """
    return compose(y, inverse(x))


def apply(pose, points):
    """Transforms points ``(*, N, 2)`` by poses ``(*, 3)``."""
    pose, points = jnp.asarray(pose), jnp.asarray(points)
    return rotate(pose[..., None, 2], points) + pose[..., None, :2]


def to_matrix(a):
    """Homogeneous 3x3 matrices ``(*, 3, 3)``."""
    a = jnp.asarray(a)
    c, s = jnp.cos(a[..., 2]), jnp.sin(a[..., 2])
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    rows = [
        jnp.stack([c, -s, a[..., 0]], -1),
        jnp.stack([s, c, a[..., 1]], -1),
        jnp.stack([zero, zero, one], -1),
    ]
    return jnp.stack(rows, axis=-2)


def from_matrix(m):
    """Poses ``(*, 3)`` from homogeneous matrices ``(*, 3, 3)``."""
    m = jnp.asarray(m)
    return make(m[..., 0, 2], m[..., 1, 2], jnp.arctan2(m[..., 1, 0], m[..., 0, 0]))


def circular_mean(theta, weights=None, axis=-1):
    """Weighted circular mean of angles via ``atan2`` of mean sine and cosine.

    Args:
        theta: angles in radians.
        weights: optional non-negative weights broadcastable to ``theta`` (a mask works).
        axis: axis to reduce.

    Returns:
        The mean angle in ``[-pi, pi]``. With all weights zero the result is 0.
    """
    theta = jnp.asarray(theta)
    w = jnp.ones_like(theta) if weights is None else jnp.broadcast_to(weights, theta.shape)
    w = w.astype(theta.dtype)
    s = jnp.sum(w * jnp.sin(theta), axis=axis)
    c = jnp.sum(w * jnp.cos(theta), axis=axis)
    return wrap(jnp.arctan2(s, c))


def mean_pose(poses, weights=None, axis=-2):
    """Mean of poses: arithmetic for position, circular for heading.

    Args:
        poses: ``(..., M, ..., 3)`` with the reduced axis ``axis`` (counted on ``poses``).
        weights: optional weights with the shape of ``poses[..., 0]``; zero weights drop entries.
        axis: the axis of ``poses`` to average over (must not be the last axis).

    Returns:
        Mean poses with ``axis`` removed. With all weights zero the position is 0.
    """
    poses = jnp.asarray(poses)
    w = jnp.ones(poses.shape[:-1], poses.dtype) if weights is None else weights
    w = jnp.broadcast_to(w, poses.shape[:-1]).astype(poses.dtype)
    ax = axis if axis >= 0 else axis + poses.ndim
    total = jnp.sum(w, axis=ax)
    safe = jnp.where(total > 0, total, 1.0)
    xy = jnp.sum(w[..., None] * poses[..., :2], axis=ax) / safe[..., None]
    theta = circular_mean(poses[..., 2], w, axis=ax)
    return jnp.concatenate([xy, theta[..., None]], axis=-1)


def distance_pair(a, b):
    """The (planar distance, absolute wrapped angle difference) between poses.

    Units are never mixed: callers threshold each component separately.

    Returns:
        ``(dxy, dtheta)``, each of the broadcast leading shape; ``dtheta`` in ``[0, pi]``.
    """
    a, b = jnp.asarray(a), jnp.asarray(b)
    d = a[..., :2] - b[..., :2]
    dxy = jnp.sqrt(jnp.sum(d * d, axis=-1))
    return dxy, jnp.abs(angle_diff(a[..., 2], b[..., 2]))


def wrap_host(theta):
    """Wraps angles to ``[-pi, pi]`` in float64 NumPy (the host twin of ``wrap``; a Python
    float in, a NumPy float out)."""
    theta = np.asarray(theta, np.float64)
    return np.arctan2(np.sin(theta), np.cos(theta))


def compose_host(a, b) -> np.ndarray:
    """``a b`` for pose rows ``(*, 3)`` in float64 NumPy (the host twin of ``compose``: no
    compilation per shape, no float32 rounding of large frame offsets)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_host(a[..., 2] + b[..., 2])], -1)


def inverse_host(a) -> np.ndarray:
    """Group inverse of pose rows ``(*, 3)`` in float64 NumPy (host twin of ``inverse``)."""
    a = np.asarray(a, np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(c * a[..., 0] + s * a[..., 1])
    y = -(-s * a[..., 0] + c * a[..., 1])
    return np.stack([x, y, wrap_host(-a[..., 2])], -1)
