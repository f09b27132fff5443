"""Kernels of the Monte Carlo localization peer: motion model, scan model, resampling, statistics.

Pure functions on one particle cloud; ``mcl.py`` scans them over time and vmaps them over runs
and seeds. The models follow Thrun, Burgard and Fox, *Probabilistic Robotics*, as AMCL (ROS
``amcl`` / ``nav2_amcl``) implements them:

* ``sample_motion``: ``sample_motion_model_odometry`` (rot1, trans, rot2, noise alpha1..4);
* ``likelihood_table`` + ``scan_loglik``: the likelihood-field range-finder model on the
  floor plan's wall distance field, nearest-cell lookup, distances capped at ``max_dist``;
* ``on_map``: the map prior of ``motion_model_with_map`` (a move through a wall is off-map);
* ``low_variance_resample``: systematic resampling;
* ``sample_free``: uniform poses over the free cells of the floor plan.

Clouds are ``(N, 3)`` poses ``(x, y, yaw)`` in the floor-plan frame B.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mfcl_jax import se2

__all__ = [
    "sample_motion",
    "likelihood_table",
    "select_beams",
    "scan_loglik",
    "on_map",
    "low_variance_resample",
    "free_cdf",
    "sample_free",
    "cloud_stats",
]

# Below this step length (m) the direction of travel is noise: the step is a pure rotation.
_MIN_TRANS = 0.01


def sample_motion(key, particles, prev, cur, alpha):
    """Moves every particle by the odometry step ``prev -> cur`` with sampled noise.

    Args:
        key: PRNG key.
        particles: ``(N, 3)`` poses in B.
        prev, cur: ``(3,)`` odometry poses in L before and after the step.
        alpha: ``(4,)`` noise coefficients: alpha1 rotation from rotation, alpha2 rotation
            from translation, alpha3 translation from translation, alpha4 translation from
            rotation (standard deviations ``sqrt(a1 rot^2 + a2 trans^2)`` etc., as AMCL).

    Returns:
        ``(N, 3)`` moved poses. With ``alpha = 0`` this is ``p * (prev^-1 cur)`` for each ``p``
        (steps under 1 cm are applied along the heading).
    """
    d = cur[:2] - prev[:2]
    trans = jnp.sqrt(jnp.sum(d * d))
    heading = jnp.arctan2(d[1], d[0])
    rot1 = jnp.where(trans < _MIN_TRANS, 0.0, se2.angle_diff(heading, prev[2]))
    rot2 = se2.angle_diff(se2.angle_diff(cur[2], prev[2]), rot1)
    # Driving backwards turns rot1 by pi; the noise must scale with the small turn, not pi.
    r1 = jnp.minimum(jnp.abs(rot1), jnp.abs(se2.angle_diff(rot1, jnp.pi)))
    r2 = jnp.minimum(jnp.abs(rot2), jnp.abs(se2.angle_diff(rot2, jnp.pi)))
    a1, a2, a3, a4 = alpha[0], alpha[1], alpha[2], alpha[3]
    sd = jnp.stack(
        [
            jnp.sqrt(a1 * r1 * r1 + a2 * trans * trans),
            jnp.sqrt(a3 * trans * trans + a4 * (r1 * r1 + r2 * r2)),
            jnp.sqrt(a1 * r2 * r2 + a2 * trans * trans),
        ]
    )
    e = jax.random.normal(key, (particles.shape[0], 3), particles.dtype) * sd
    h_rot1 = rot1 - e[:, 0]
    h_trans = trans - e[:, 1]
    h_rot2 = rot2 - e[:, 2]
    th = particles[:, 2] + h_rot1
    return jnp.stack(
        [
            particles[:, 0] + h_trans * jnp.cos(th),
            particles[:, 1] + h_trans * jnp.sin(th),
            se2.wrap(th + h_rot2),
        ],
        axis=-1,
    )


def _beam_logp(d, sigma_hit, z_hit, z_rand, max_range):
    # Thrun's p_hit is the normalised Gaussian density; AMCL drops 1 / (sqrt(2 pi) sigma),
    # which only rescales the weight of z_rand against it.
    hit = jnp.exp(-0.5 * jnp.square(d / sigma_hit)) / (jnp.sqrt(2.0 * jnp.pi) * sigma_hit)
    return jnp.log(z_hit * hit + z_rand / max_range)


def likelihood_table(dist, sigma_hit, z_hit, z_rand, max_range, max_dist):
    """Per-cell log-likelihood of one beam end point, with a border of off-grid cells.

    Args:
        dist: ``(H, W)`` distance to the nearest wall solid (m).
        sigma_hit, z_hit, z_rand, max_range: the likelihood-field model's parameters.
        max_dist: distances are capped here (AMCL's ``laser_likelihood_max_dist``), so that a
            beam through an unmapped opening costs a bounded amount; off the grid reads it too.

    Returns:
        ``(H + 2, W + 2)``: cell ``(iy, ix)`` of ``dist`` is entry ``(iy + 1, ix + 1)``; the
        border lets a lookup clip instead of testing bounds.
    """
    logp = _beam_logp(jnp.minimum(dist, max_dist), sigma_hit, z_hit, z_rand, max_range)
    far = _beam_logp(max_dist, sigma_hit, z_hit, z_rand, max_range)
    return jnp.pad(logp, 1, constant_values=far)


def select_beams(points, mask, n_beams: int):
    """``n_beams`` points picked evenly (by rank) among the valid points of one scan.

    Args:
        points: ``(P, 2)`` scan points, ordered by beam angle.
        mask: ``(P,)`` bool, valid points.
        n_beams: static count.

    Returns:
        ``(n_beams, 2)`` points and ``(n_beams,)`` bool (False when the scan has fewer valid
        points; each valid point is then used once).
    """
    n_valid = jnp.sum(mask.astype(jnp.int32))
    i = jnp.arange(n_beams, dtype=jnp.int32)
    span = jnp.maximum(n_valid, n_beams).astype(jnp.float32)
    rank = jnp.floor((i.astype(jnp.float32) + 0.5) * span / n_beams).astype(jnp.int32)
    cum = jnp.cumsum(mask.astype(jnp.int32))
    idx = jnp.searchsorted(cum, rank + 1, side="left")
    idx = jnp.clip(idx, 0, points.shape[0] - 1)
    return points[idx], i < n_valid


# Particles per block of the scan model: the (block, n_beams) intermediates then stay in cache
# (at 16384 particles unblocked, the step costs 1.6x more per particle on a 2-core CPU).
_BLOCK = 1024


def scan_loglik(particles, beams, beam_mask, table, origin, res: float):
    """Log-likelihood of one scan at every particle (before tempering).

    Args:
        particles: ``(N, 3)`` sensor poses in B.
        beams: ``(n_beams, 2)`` points in the sensor frame; ``beam_mask`` ``(n_beams,)``.
        table: ``(H + 2, W + 2)`` from ``likelihood_table`` (with its off-grid border).
        origin: ``(2,)`` grid origin; ``res``: cell size (static).

    Returns:
        ``(N,)`` summed log-likelihood over the valid beams.
    """
    n = particles.shape[0]
    if n <= _BLOCK:
        return _scan_loglik(particles, beams, beam_mask, table, origin, res)
    m = -(-n // _BLOCK)
    padded = jnp.concatenate([particles, jnp.zeros((m * _BLOCK - n, 3), particles.dtype)])
    out = jax.lax.map(
        lambda p: _scan_loglik(p, beams, beam_mask, table, origin, res),
        padded.reshape(m, _BLOCK, 3),
    )
    return out.reshape(-1)[:n]


def _scan_loglik(particles, beams, beam_mask, table, origin, res):
    h, w = table.shape
    c = jnp.cos(particles[:, 2:3])
    s = jnp.sin(particles[:, 2:3])
    bx, by = beams[None, :, 0] / res, beams[None, :, 1] / res
    # Cell (iy, ix) has its centre at origin + res (ix + 0.5, iy + 0.5): the nearest cell is
    # floor((p - origin) / res), plus 1 for the border.
    fx = (particles[:, 0:1] - origin[0]) / res + 1.0
    fy = (particles[:, 1:2] - origin[1]) / res + 1.0
    ix = jnp.clip(jnp.floor(fx + c * bx - s * by), 0, w - 1).astype(jnp.int32)
    iy = jnp.clip(jnp.floor(fy + s * bx + c * by), 0, h - 1).astype(jnp.int32)
    v = table.reshape(-1)[iy * w + ix]
    return v @ beam_mask.astype(v.dtype)


def on_map(before, after, passable, origin, res: float, n_sub: int = 4):
    """Whether each particle's move stays on the map's passable space, ``(N,)`` bool.

    The straight move from ``before`` to ``after`` is checked at ``n_sub`` evenly spaced
    points ending at ``after``: a 0.25 m keyframe step would otherwise hop over a 0.2 m wall
    unseen. Moves longer than ``n_sub`` times the thinnest wall can still hop over it.

    Args:
        before, after: ``(N, 3)`` poses in B.
        passable: ``(H, W)`` bool, inside the building and not in a wall (door openings
            included); off the grid is not passable.
        origin: ``(2,)`` grid origin; ``res``: cell size (static).
        n_sub: static number of checked points.
    """
    h, w = passable.shape
    f = jnp.arange(1, n_sub + 1, dtype=after.dtype) / n_sub
    xy = before[:, None, :2] + f[None, :, None] * (after[:, None, :2] - before[:, None, :2])
    ix = jnp.floor((xy[..., 0] - origin[0]) / res).astype(jnp.int32)
    iy = jnp.floor((xy[..., 1] - origin[1]) / res).astype(jnp.int32)
    ok = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    ok = ok & passable[jnp.clip(iy, 0, h - 1), jnp.clip(ix, 0, w - 1)]
    return jnp.all(ok, axis=-1)


def low_variance_resample(key, weights):
    """Systematic resampling: indices of the surviving particles.

    Args:
        key: PRNG key.
        weights: ``(N,)`` non-negative weights (need not be normalised; not all zero).

    Returns:
        ``(N,)`` int32 indices, non-decreasing; particle ``i`` is drawn ``N w_i`` times up to
        rounding (never more than ``ceil(N w_i)``, never fewer than ``floor(N w_i)``).
    """
    n = weights.shape[0]
    cdf = jnp.cumsum(weights)
    cdf = cdf / cdf[-1]
    u = jax.random.uniform(key, (), cdf.dtype)
    # The pointers are (u + j) / n, j = 0..n-1. Instead of a binary search per pointer, count
    # the pointers below each cumulative weight, c_i = #{j : (u + j) / n < cdf_i}; pointer j
    # then lands on particle #{i : c_i <= j}: a histogram of c and a cumulative sum, O(n).
    c = jnp.clip(jnp.ceil(n * cdf - u), 0, n).astype(jnp.int32)
    idx = jnp.cumsum(jnp.zeros(n + 1, jnp.int32).at[c].add(1))[:n]
    # Rounding can leave cdf_{n-1} a hair below 1: its last pointers fall on the last particle.
    return jnp.minimum(idx, n - 1)


def free_cdf(free):
    """Running count of free cells over the row-major flattened grid, ``(H * W,)`` int32."""
    return jnp.cumsum(free.reshape(-1).astype(jnp.int32))


def sample_free(key, cdf, shape, origin, res: float, n: int):
    """``n`` poses uniform over the free cells (uniform within a cell) and uniform in yaw.

    Args:
        key: PRNG key.
        cdf: ``(H * W,)`` from ``free_cdf`` (its last entry, the free-cell count, must be > 0).
        shape: static ``(H, W)``.
        origin: ``(2,)`` grid origin; ``res``: cell size (static).
        n: static count.

    Returns:
        ``(n, 3)`` poses in B.
    """
    k_cell, k_jit, k_yaw = jax.random.split(key, 3)
    total = cdf[-1]
    # The k-th free cell (0-based) is the first whose running count exceeds k. Row-major rank
    # does not change when a grid is padded on the right or the top, so a run samples the same
    # cells whatever shape bucket it is padded to.
    rank = jnp.floor(jax.random.uniform(k_cell, (n,)) * total.astype(jnp.float32))
    rank = jnp.minimum(rank.astype(jnp.int32), total - 1)
    cell = jnp.searchsorted(cdf, rank, side="right").astype(jnp.int32)
    iy, ix = cell // shape[1], cell % shape[1]
    u = jax.random.uniform(k_jit, (n, 2))
    x = origin[0] + res * (ix.astype(jnp.float32) + u[:, 0])
    y = origin[1] + res * (iy.astype(jnp.float32) + u[:, 1])
    yaw = jax.random.uniform(k_yaw, (n,), minval=-jnp.pi, maxval=jnp.pi)
    return jnp.stack([x, y, yaw], axis=-1)


def cloud_stats(particles, weights):
    """Weighted mean pose and spread of a cloud.

    Args:
        particles: ``(N, 3)``.
        weights: ``(N,)`` normalised weights.

    Returns:
        ``(mean (3,), std_xy, std_yaw, ess)``: circular mean for yaw; ``std_xy`` the RMS
        distance to the mean position (m, ``sqrt(var_x + var_y)``); ``std_yaw`` the circular
        standard deviation ``sqrt(-2 ln R)`` (rad, ``R`` the mean resultant length); ``ess``
        the effective sample size ``1 / sum w^2``.
    """
    c, s = jnp.cos(particles[:, 2]), jnp.sin(particles[:, 2])
    mc, ms = jnp.sum(weights * c), jnp.sum(weights * s)
    mx, my = jnp.sum(weights * particles[:, 0]), jnp.sum(weights * particles[:, 1])
    mean = jnp.stack([mx, my, jnp.arctan2(ms, mc)])
    # Two passes (about the mean): E|p|^2 - |E p|^2 cancels badly in float32 at 40 m.
    dx, dy = particles[:, 0] - mx, particles[:, 1] - my
    std_xy = jnp.sqrt(jnp.sum(weights * (dx * dx + dy * dy)))
    r = jnp.clip(jnp.hypot(mc, ms), 1e-12, 1.0)
    std_yaw = jnp.sqrt(-2.0 * jnp.log(r))
    ess = 1.0 / jnp.sum(weights * weights)
    return mean, std_xy, std_yaw, ess
