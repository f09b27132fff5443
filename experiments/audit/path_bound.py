"""Upper bounds on the path's log-likelihood over a cell of placements.

The uniqueness test (``decision.uniqueness``) compares the best placement ``A*`` of the path
with the best competitor a grid search finds (5 deg, 0.4-0.5 m cells, then polished); a
competitor narrower than a grid cell can slip through. The branch and bound of
``path_certify`` answers the question over the continuum, on the path's log-likelihood ``L``
(``path_llr``), with the bounds of this module: each holds for every placement inside a cell.

Placements are parametrised about the path's centre ``c``: ``a(p) = R(theta) (p - c) + u``.
A *cell* is the set of placements with ``|theta - theta0| <= delta`` and ``u`` in the square
of half-side ``h`` about ``u0``. Under any placement of the cell, a point ``p`` lies within
``rho(p) = sqrt(2) h + |p - c| delta`` of where the cell's centre puts it (``x``).

Bound on a return. The plan's distance field (to a wall's surface) is 1-Lipschitz between
any two nodes; capped at ``cap`` (< 1 m, where a return's likelihood is already at its floor
``z_rand``) it is ``cap`` on and beyond the grid's border, padding included (``bound_fields``).
The distance ``L`` reads (bilinear) at any point within ``rho`` of ``x`` is then at least
``max(D(x) - sqrt(2) rho, d(v) - rho - sqrt(2) res - |x - v|)`` (``D``: bilinear of the capped
nodes, whose gradient is at most ``sqrt(2)``; ``v``: the node nearest to ``x``), and a
return's log-likelihood falls with the distance, so its likelihood at that lower bound bounds
it from above.

Bound on a free sample. Its obstacle reading is at least the reading at ``x`` less
``sqrt(2) rho / res`` (the bilinear field's gradient), and it is 1 (the sample counts
``log(1 - z_block)``) when every node within ``rho + sqrt(2) res`` of ``x`` is solid (a wall,
a plan's outside; an occupancy map's unobserved outside, 0.5, is not).

Clusters. At a coarse level one lookup per voxel of the centred path (side ``h``) serves all
its points (``voxels``): ``rho`` grows by the voxel's half-diagonal and the voxel's weight is
the sum of its points'. The bound of a cell is the sum over voxels; it is never below ``L`` of
any placement in the cell (``tests/test_path_bound.py`` checks that on sampled placements).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from scipy import ndimage

from mfcl_jax.frontend.path_fields import PlanFields, sample_field

__all__ = ["BoundFields", "bound_fields", "cell_bounds", "solid", "voxels", "SQ2", "EPS"]

SQ2 = math.sqrt(2.0)
EPS = 1e-3  # m: float32 slack on every displacement


@dataclass(frozen=True)
class BoundFields:
    """The plan as the bound reads it (host arrays, the search's grid)."""

    capped: np.ndarray  # (H, W) min(distance to a wall, cap), 1-Lipschitz with cap outside
    to_free: np.ndarray  # (H, W) distance from each node to the nearest non-solid node (m)
    bad: np.ndarray  # (H, W) the obstacle field (``PlanFields.bad``)
    outside: float  # the obstacle field off the grid
    origin: np.ndarray  # (2,)
    res: float
    cap: float


def bound_fields(fields: PlanFields) -> BoundFields:
    """``BoundFields`` of the search's ``PlanFields`` (host).

    The wall nodes are those at distance 0; the distance is measured again over the whole
    (bucket-padded) grid as the raster measures it (``floorplan.raster``), so it equals the
    field ``L`` reads on the plan's raster, stays below it on the padding (10 m there) and is
    1-Lipschitz between any two nodes. ``cap`` stays a node's distance below the least
    wall-distance on the grid's border, so the capped field is ``cap`` off the grid too."""
    dist = np.asarray(fields.dist, np.float64)
    res = float(fields.res)
    wall = dist <= 1e-6
    edt = ndimage.distance_transform_edt(~wall) * res if wall.any() else np.full(dist.shape, 1e6)
    # as the raster measures it: to the wall's surface, half a cell short of the wall node
    edt = np.where(wall, 0.0, np.maximum(edt - 0.5 * res, 0.0))
    border = np.concatenate([edt[0], edt[-1], edt[:, 0], edt[:, -1]])
    cap = float(min(1.0, border.min() - res))
    if cap <= 0:
        raise ValueError(f"path_bound: walls on the plan grid's border (cap {cap:.2f} m)")
    free = ~solid(fields.bad)
    to_free = (ndimage.distance_transform_edt(~free) * res if free.any()
               else np.full(dist.shape, 1e6))  # fmt: skip
    return BoundFields(
        capped=np.minimum(edt, cap).astype(np.float32),
        to_free=to_free.astype(np.float32),
        bad=np.asarray(fields.bad, np.float32),
        outside=float(fields.outside),
        origin=np.asarray(fields.origin, np.float64),
        res=res,
        cap=cap,
    )


def solid(bad) -> np.ndarray:
    """The nodes whose obstacle field is 1 (walls, a plan's outside): only a sample whose
    every neighbour is solid surely pays the whole ``log(1 - z_block)``; nodes of an occupancy
    map's unobserved outside (0.5) count as not solid, which keeps every bound an upper bound."""
    return np.asarray(bad) >= 1.0 - 1e-6


def _nearest(field, origin, res, xy):
    """The value at the in-grid node nearest to ``xy`` and the distance to that node."""
    h, w = field.shape
    iu = jnp.clip(jnp.round((xy[..., 0] - origin[0]) / res - 0.5), 0, w - 1)
    iv = jnp.clip(jnp.round((xy[..., 1] - origin[1]) / res - 0.5), 0, h - 1)
    nx = origin[0] + (iu + 0.5) * res
    ny = origin[1] + (iv + 0.5) * res
    val = field.reshape(-1)[iv.astype(jnp.int32) * w + iu.astype(jnp.int32)]
    return val, jnp.hypot(xy[..., 0] - nx, xy[..., 1] - ny)


@jax.jit
def cell_bounds(cells, h, delta, pq, pw, pr, fq, fw, fr, capped, to_free, bad, outside, origin,
                res, cap, sigma, z_rand, z_block):  # fmt: skip
    """Upper bounds of ``L`` over cells ``(N, 3)`` (``u0x, u0y, theta0``) of half-side ``h``
    and half-width ``delta``; ``pq, pw, pr``: voxel centres ``(M, 2)`` of the centred
    returns, their weights and half-diagonals; ``fq, fw, fr``: the same for free samples."""
    c, s = jnp.cos(cells[:, 2]), jnp.sin(cells[:, 2])

    def place(q):
        x = c[:, None] * q[None, :, 0] - s[:, None] * q[None, :, 1] + cells[:, None, 0]
        y = s[:, None] * q[None, :, 0] + c[:, None] * q[None, :, 1] + cells[:, None, 1]
        return jnp.stack([x, y], -1)

    rho = SQ2 * h + (jnp.hypot(pq[:, 0], pq[:, 1]) + pr) * delta + pr + EPS
    xp = place(pq)
    lb_bil = sample_field(capped, origin, res, xp, cap) - SQ2 * rho
    dv, dn = _nearest(capped, origin, res, xp)
    lb = jnp.maximum(jnp.maximum(lb_bil, dv - rho - SQ2 * res - dn), 0.0)
    f = jnp.log((1.0 - z_rand) * jnp.exp(-lb * lb / (2.0 * sigma**2)) + z_rand)
    ub = jnp.sum(pw * f, axis=1)
    rho_f = SQ2 * h + (jnp.hypot(fq[:, 0], fq[:, 1]) + fr) * delta + fr + EPS
    xf = place(fq)
    ev, en = _nearest(to_free, origin, res, xf)
    # the obstacle field's bilinear reading moves by at most sqrt(2) / res per metre
    b = jnp.maximum(sample_field(bad, origin, res, xf, outside) - SQ2 * rho_f / res, 0.0)
    b = jnp.where(ev - en > rho_f + SQ2 * res, 1.0, jnp.minimum(b, 1.0))
    return ub + jnp.sum(fw * jnp.log(1.0 - z_block * b), axis=1)


def voxels(q, w, side: float, n_min: int = 64):
    """Voxel centres, summed weights and half-diagonals of points ``q`` with weights ``w``
    (padded to a power of two, at least ``n_min``); ``side`` 0 keeps the points."""
    keep = w > 0
    q, w = q[keep], w[keep]
    if side > 0 and len(q):
        key = np.floor(q / side).astype(np.int64)
        uk, inv = np.unique(key, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        wsum = np.bincount(inv, weights=w, minlength=len(uk))
        cen = (uk + 0.5) * side
        half = side * SQ2 / 2
    else:
        cen, wsum, half = q, w, 0.0
    n = max(n_min, 1 << max(0, (len(cen) - 1).bit_length()))
    out_q = np.zeros((n, 2), np.float32)
    out_w = np.zeros(n, np.float32)
    out_q[: len(cen)], out_w[: len(cen)] = cen, wsum
    return out_q, out_w, np.float32(half)
