"""Continuous refinement of candidate poses: an optax optimiser on the verification score.

The objective is the occupancy term of ``verify.score``, ``f(Y) = mean_k exp(-d(Y p_k)^2 / 2
sigma^2)`` with ``d`` the bilinear signed wall-surface distance (``verify.sample``): smooth in
``Y`` and maximised over ``u = (x, y, yaw_lever * theta)``, the heading in metres of arc so that
all three coordinates share one unit. ``sigma`` shrinks geometrically from ``sigma_refine``
(capture range of a Hough peak, ~0.5 m / 2 deg) to ``sigma_occ`` (the scoring width) over the
first half of the steps and stays there, so the final steps optimise the very score that later
decides whether the refined pose is kept.

The optimiser is an optax chain, run in ``lax.scan`` over the steps with all candidates of a
submap stepping together (``vmap`` inside each step; the caller batches the submaps):

    scale_by_gauss_newton  ->  clip_by_global_norm(refine_max_step)  ->  scale(-1)

``scale_by_gauss_newton`` preconditions the gradient of ``-f`` by ``(N + lam I)^-1``, with ``N =
J^T W J / (n sigma^2)`` the Gauss-Newton normal matrix of the residuals ``d(Y p_k)`` (``J`` their
``(n, 3)`` Jacobian, ``W`` the kernel weights). For this Welsch-robust least-squares objective
that is the iteratively reweighted Gauss-Newton step: it converges in about ten steps to well
under a centimetre, where adam (per-coordinate scaling, no curvature) needs several times more
steps and stalls at the bilinear cell's kinks. The relative Levenberg damping ``lam`` keeps a
direction that no wall constrains (a corridor's axis) in place instead of letting it drift; the
clip bounds a step to ``refine_max_step`` metres (of arc, for the heading).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax

from mfcl_jax import se2
from mfcl_jax.frontend import verify

__all__ = ["refine", "sigma_schedule", "scale_by_gauss_newton", "grad_and_normal"]

DAMPING = 1e-3  # Levenberg damping, relative to the mean eigenvalue of the normal matrix


def sigma_schedule(p) -> np.ndarray:
    """``(refine_steps,)`` kernel widths: geometric ``sigma_refine -> sigma_occ``, then flat."""
    n = p.refine_steps
    k = max(1, n // 2)
    s = np.geomspace(p.sigma_refine, p.sigma_occ, k) if k > 1 else np.array([p.sigma_occ])
    return np.concatenate([s, np.full(n - k, p.sigma_occ)]).astype(np.float32)


def _solve3(a, b):
    """Solves the symmetric ``(3, 3)`` system ``a x = b`` by cofactors (no LAPACK call: the
    batched LU of XLA:CPU costs more than the whole step)."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[1, 2]
    c01 = a[0, 2] * a[1, 2] - a[0, 1] * a[2, 2]
    c02 = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    c11 = a[0, 0] * a[2, 2] - a[0, 2] * a[0, 2]
    c12 = a[0, 1] * a[0, 2] - a[0, 0] * a[1, 2]
    c22 = a[0, 0] * a[1, 1] - a[0, 1] * a[0, 1]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    x = jnp.stack(
        [
            c00 * b[0] + c01 * b[1] + c02 * b[2],
            c01 * b[0] + c11 * b[1] + c12 * b[2],
            c02 * b[0] + c12 * b[1] + c22 * b[2],
        ]
    )
    return x / det


def scale_by_gauss_newton(damping: float = DAMPING) -> optax.GradientTransformationExtraArgs:
    """Preconditions a ``(3,)`` gradient by ``(N + lam I)^-1`` (``N`` passed as ``normal=``).

    ``lam = damping * trace(N) / 3`` (plus a floor), so the damping is scale-free. A singular or
    non-finite system yields a zero update rather than NaN.

    Args:
        damping: relative Levenberg damping (>= 0).

    Returns:
        A stateless ``optax.GradientTransformationExtraArgs``; its ``update`` needs the keyword
        ``normal``, a ``(3, 3)`` symmetric positive semi-definite matrix in the units of the
        parameters.
    """
    if not damping >= 0:
        raise ValueError(f"scale_by_gauss_newton: damping must be >= 0, got {damping=}")

    def init_fn(params):
        del params
        return optax.EmptyState()

    def update_fn(updates, state, params=None, *, normal, **extra_args):
        del params, extra_args
        lam = damping * jnp.trace(normal) / 3 + 1e-6
        step = _solve3(normal + lam * jnp.eye(3, dtype=normal.dtype), updates)
        return jnp.where(jnp.all(jnp.isfinite(step)), step, 0.0), state

    return optax.GradientTransformationExtraArgs(init_fn, update_fn)


def _unscale(lever):
    """``(3,)`` factors from ``u = (dx, dy, lever * dtheta)`` back to a pose offset."""
    one = jnp.ones((), lever.dtype)
    return jnp.stack([one, one, one / lever])


def _sums(*xs):
    """Sums of same-shape arrays over their last axis in ONE pass (a variadic reduce): XLA:CPU
    gives each plain sum its own pass over a materialised product, nine of them here."""
    zero = jnp.zeros((), xs[0].dtype)
    add = lambda a, b: tuple(u + v for u, v in zip(a, b, strict=True))  # noqa: E731
    return jax.lax.reduce(xs, (zero,) * len(xs), add, (xs[0].ndim - 1,))


def _grad_normal(pose, rot, lever, pts, okf, feats, sigma):
    """``grad_and_normal`` at ``pose (3,)`` with ``rot`` its ``(cos, sin)``."""
    r = feats.rasters
    c, s = rot
    rx = c * pts[:, 0] - s * pts[:, 1]
    ry = s * pts[:, 0] + c * pts[:, 1]
    d, gx, gy = verify.sample_xy(
        r.origin, r.res, feats.sdf4, rx + pose[0], ry + pose[1], verify.FAR, grad=True
    )
    # Products with per-step reciprocals: a division per point is the dearest scalar op here.
    gt = (gy * rx - gx * ry) * (1.0 / lever)  # d(d)/d(u_2): R'(theta) p = (-ry, rx)
    w = okf * jnp.exp(-0.5 * (d * (1.0 / sigma)) ** 2)
    wd = w * d
    sums = _sums(
        wd * gx, wd * gy, wd * gt, w * gx * gx, w * gx * gy, w * gx * gt, w * gy * gy,
        w * gy * gt, w * gt * gt,
    )  # fmt: skip
    cst = 1.0 / (jnp.maximum(jnp.sum(okf), 1.0) * sigma**2)
    g0, g1, g2, n00, n01, n02, n11, n12, n22 = (cst * v for v in sums)
    grad = jnp.stack([g0, g1, g2])
    rows = ((n00, n01, n02), (n01, n11, n12), (n02, n12, n22))
    return grad, jnp.stack([jnp.stack(row) for row in rows])


def grad_and_normal(u, pose0, lever, pts, okf, feats, sigma):
    """Gradient of ``-f`` and the Gauss-Newton normal matrix, at ``u`` (``pose0`` + offset).

    The residual ``d_k = d(Y p_k)`` has the Jacobian ``J_k = (g_x, g_y, g . R'(theta) p_k /
    lever)`` in ``u`` (``g`` the bilinear field gradient, exact: ``verify.sample_xy``), and the
    gradient is the chain rule through it, ``-df/du = J^T (w d) / (n sigma^2)``, the exact
    gradient of the bilinear objective. One field lookup per point gives all of it.

    Args:
        u: ``(3,)`` offset ``(dx, dy, lever * dtheta)``; ``pose0`` ``(3,)`` the start pose.
        lever: metres of arc per radian of heading.
        pts: ``(n, 2)`` points (submap frame), ``okf`` ``(n,)`` float mask.
        feats: ``FloorplanFeatures``; sigma: kernel width (m).

    Returns:
        ``(grad (3,), normal (3, 3))``.
    """
    pose = pose0 + u * _unscale(lever)
    return _grad_normal(pose, (jnp.cos(pose[2]), jnp.sin(pose[2])), lever, pts, okf, feats, sigma)


def refine(poses, pts, ok, feats, p):
    """Refines ``(J, 3)`` poses of one submap; returns refined ``(J, 3)`` poses.

    All ``J`` candidates step together, so that each step computes their rotations once
    (``verify.rotation``) before the per-point work.

    Args:
        poses: ``(J, 3)`` initial candidates.
        pts, ok: ``(n, 2)`` occupied points and mask (submap frame).
        feats: ``FloorplanFeatures`` (``sdf4`` and the raster geometry).
        p: ``FrontendParams`` (``refine_steps``, ``sigma_refine``, ``sigma_occ``,
            ``refine_max_step``, ``yaw_lever``).
    """
    okf = ok.astype(jnp.float32)
    lever = jnp.asarray(p.yaw_lever, jnp.float32)
    unscale = _unscale(lever)
    sig = jnp.asarray(sigma_schedule(p))
    opt = optax.chain(
        scale_by_gauss_newton(DAMPING),
        optax.clip_by_global_norm(p.refine_max_step),
        optax.scale(-1.0),
    )

    def update(g, st, u, nrm):
        return opt.update(g, st, u, normal=nrm)

    def step(carry, sigma):
        u, st = carry
        pose = poses + u * unscale
        c, s = verify.rotation(pose)
        gn = lambda y, c, s: _grad_normal(y, (c, s), lever, pts, okf, feats, sigma)  # noqa: E731
        g, nrm = jax.vmap(gn)(pose, c, s)
        # optax mixes Python floats into its arithmetic: standard promotion here even when
        # the caller runs with strict promotion (tests do).
        with jax.numpy_dtype_promotion("standard"):
            upd, st = jax.vmap(update)(g, st, u, nrm)
            u = optax.apply_updates(u, upd)
        return (u, st), None

    u0 = jnp.zeros_like(poses)
    with jax.numpy_dtype_promotion("standard"):
        st0 = jax.vmap(opt.init)(u0)
    (u, _), _ = jax.lax.scan(step, (u0, st0), sig)
    pose = poses + u * unscale
    return jnp.concatenate([pose[:, :2], se2.wrap(pose[:, 2:])], -1)
