"""The log-likelihood of the whole path seen so far under a placement in the plan.

The observation model, fixed for every building:

* a LiDAR return at distance ``d`` from the nearest plan wall has likelihood
  ``(1 - z_rand) exp(-d^2 / 2 sigma^2) + z_rand``: a likelihood field whose floor ``z_rand``
  stands for clutter and as-built changes the plan does not hold (a return off the plan costs
  at most ``log z_rand``, whatever the placement);
* a free-space sample (along a ray, or the sensor itself) in a cell of occupancy ``b`` has
  likelihood ``1 - z_block b``: ``b`` is 1 in a wall and outside a plan's building, 0 in its
  rooms, so a placement under which the robot saw through a wall, or stood in one, loses;
  an occupancy map's never-observed outside holds ``b = 0.5`` (``raster.UNOBSERVED``): a free
  sample in a stretch the map lacks costs ``log 0.55``, not the ``log 0.1`` of a wall;
* the returns of one scan are not independent (one surface, many beams), nor are the scans of
  one metre of travel (one view, seen again): each scan contributes the MEAN log-likelihood of
  its returns and of its free samples, weighted by the metres of travel per scan, so the
  evidence counts one observation per metre (``metre``).

``L(A) = sum over scans s of kappa * (mean_i log p(z_i | A) + mean_j log p(free_j | A))``,
``kappa`` the path's length over its number of distinct scans (over ``metre``).

A scan seen by several windows (their submaps overlap) is one scan: evidence points are
grouped by their sensor position (to a centimetre), so overlapping windows add no evidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.frontend.path_fields import PlanFields, sample_field

__all__ = ["LLRParams", "PathEvidence", "path_evidence", "log_likelihood", "refine", "REFINE_STEPS"]


@dataclass(frozen=True)
class LLRParams:
    """Settings of the observation model (static; one setting for every building)."""

    sigma: float = 0.15  # m: wall-hit kernel
    z_rand: float = 0.1  # floor of a return's likelihood
    z_block: float = 0.9  # a free sample in a wall or outside a plan keeps 1 - z_block
    metre: float = 1.0  # m of travel counted as one observation
    ray_fracs: tuple = (0.3, 0.6, 0.85)  # free samples along each evidence ray
    max_points: int = 2048
    max_free: int = 2048


@dataclass(frozen=True)
class PathEvidence:
    """The path's returns and free samples in the odometry frame, with their weights."""

    pts: jax.Array  # (P, 2)
    pw: jax.Array  # (P,) weight of each return (0: padding)
    free: jax.Array  # (Q, 2)
    fw: jax.Array  # (Q,)
    n_scans: jax.Array  # () distinct scans
    length: jax.Array  # () m of travel


jax.tree_util.register_dataclass(
    PathEvidence, data_fields=list(PathEvidence.__dataclass_fields__), meta_fields=[]
)


def _per_scan(code, ok):
    """``(count of ok entries of each entry's scan, distinct scans)`` for scan ``code``s."""
    n = code.shape[0]
    big = jnp.iinfo(jnp.int32).max
    key = jnp.where(ok, code, big)
    order = jnp.argsort(key)
    sk = key[order]
    first = jnp.concatenate([jnp.ones(1, bool), sk[1:] != sk[:-1]])
    grp = jnp.cumsum(first) - 1
    cnt = jax.ops.segment_sum(ok[order].astype(jnp.float32), grp, num_segments=n)
    per = jnp.zeros(n, jnp.float32).at[order].set(cnt[grp])
    n_scans = jnp.sum(first & ok[order])
    return per, n_scans


def _even(ok, n: int):
    """Up to ``n`` indices evenly spread over the true entries of ``ok``, their validity and
    the factor that keeps a weighted sum over the kept entries an estimate of the whole."""
    m = ok.shape[0]
    order = jnp.argsort(~ok, stable=True)
    count = jnp.sum(ok)
    i = jnp.arange(n)
    spread = i.astype(jnp.float32) * (count - 1).astype(jnp.float32) / max(n - 1, 1)
    pos = jnp.where(count > n, jnp.round(spread).astype(jnp.int32), i)
    scale = jnp.maximum(count.astype(jnp.float32) / n, 1.0)
    return order[jnp.clip(pos, 0, m - 1)], i < count, scale


def path_evidence(ev_points, ev_origins, ev_mask, X, length, p: LLRParams = LLRParams()):
    """``PathEvidence`` of the windows' evidence samples ``(C, E, 2)`` (window frames; ``X``
    ``(C, 3)`` the windows' odometry poses; ``ev_mask`` false outside the path) and the
    path's ``length`` (m)."""
    q = se2.apply(X, ev_points).reshape(-1, 2)
    o = se2.apply(X, ev_origins).reshape(-1, 2)
    m = ev_mask.reshape(-1)
    c = jnp.round(o * 100.0).astype(jnp.int32)
    code = c[:, 0] * 100_003 + c[:, 1]
    per, n_scans = _per_scan(code, m)
    kappa = length / jnp.maximum(n_scans, 1).astype(jnp.float32) / p.metre
    w = jnp.where(m, kappa / jnp.maximum(per, 1.0), 0.0)
    nf = len(p.ray_fracs)
    fr = jnp.asarray(p.ray_fracs, q.dtype)[:, None, None]
    along = (o[None] + fr * (q - o)[None]).reshape(-1, 2)
    # each scan's free samples: its rays' samples and its sensor position, once
    order = jnp.lexsort((code, ~m))
    first = jnp.concatenate([jnp.ones(1, bool), code[order][1:] != code[order][:-1]])
    sensor_ok = jnp.zeros_like(m).at[order].set(first & m[order])
    free = jnp.concatenate([along, o])
    fcode = jnp.concatenate([jnp.tile(code, nf), code])
    fok = jnp.concatenate([jnp.tile(m, nf), sensor_ok])
    fper, _ = _per_scan(fcode, fok)
    fw = jnp.where(fok, kappa / jnp.maximum(fper, 1.0), 0.0)
    ip, pok, ps_ = _even(m, p.max_points)
    jf, fok2, fs_ = _even(fok, p.max_free)
    return PathEvidence(
        q[ip], jnp.where(pok, w[ip] * ps_, 0.0), free[jf], jnp.where(fok2, fw[jf] * fs_, 0.0),
        n_scans, jnp.asarray(length, jnp.float32),
    )  # fmt: skip


def log_likelihood(a, pe: PathEvidence, fields: PlanFields, p: LLRParams = LLRParams()):
    """``L(a)``: the path's log-likelihood under the placement ``a (3,)`` (module docstring)."""
    d = sample_field(fields.dist, fields.origin, fields.res, se2.apply(a, pe.pts), 10.0)
    f = jnp.log((1.0 - p.z_rand) * jnp.exp(-d * d / (2.0 * p.sigma**2)) + p.z_rand)
    b = sample_field(fields.bad, fields.origin, fields.res, se2.apply(a, pe.free), fields.outside)
    g = jnp.log(1.0 - p.z_block * jnp.clip(b, 0.0, 1.0))
    return jnp.sum(pe.pw * f) + jnp.sum(pe.fw * g)


def _polish(a, pe, fields, p, step_xy, step_deg, allowed=None):
    d = jnp.arange(-1, 2, dtype=jnp.float32)
    dx, dy, dt = jnp.meshgrid(d * step_xy, d * step_xy, d * math.radians(step_deg), indexing="ij")
    cand = a + jnp.stack([dx.ravel(), dy.ravel(), dt.ravel()], -1)
    sc = jax.vmap(lambda c: log_likelihood(c, pe, fields, p))(cand)
    if allowed is not None:  # the centre (``a`` itself) is allowed: the round never leaves
        sc = jnp.where(allowed(cand), sc, -jnp.inf)
    i = jnp.argmax(sc)
    return cand[i], sc[i]


# the polish's rounds of 27 poses: (m, deg) steps
REFINE_STEPS = ((0.12, 1.2), (0.04, 0.4), (0.015, 0.15))


def refine(a, pe: PathEvidence, fields: PlanFields, p: LLRParams = LLRParams(),
           steps=REFINE_STEPS, allowed=None):  # fmt: skip
    """The best placement near ``a`` (rounds of 27 poses, ``steps``: by default 12 cm /
    1.2 deg, 4 cm / 0.4 deg, 1.5 cm / 0.15 deg) and its ``L``; with ``allowed`` (placements
    ``(N, 3)`` -> ``(N,)`` bool, true at ``a``), the best of the placements it allows."""
    for step_xy, step_deg in steps[:-1]:
        a, _ = _polish(a, pe, fields, p, step_xy, step_deg, allowed)
    return _polish(a, pe, fields, p, *steps[-1], allowed)
