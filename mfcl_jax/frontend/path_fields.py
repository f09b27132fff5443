"""The plan as the path search reads it: its settings, its fields and their bilinear lookup.

``plan_fields`` turns the floor plan's rasters into a wall-proximity field ``exp(-d^2 / 2
sigma^2)`` and an obstacle field (the occupancy the path's free samples meet: 1 in walls, 0 in
the footprint, ``Rasters.outside`` outside it and off the grid), fine for polishing and
block-reduced to a coarse cell for the FFT correlation (``path_search``); ``sample_field``
reads a field at points. Placements are evaluated on the same fields (``placements``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["SearchParams", "PlanFields", "plan_fields", "sample_field"]


@dataclass(frozen=True)
class SearchParams:
    """Static settings of the search (a change recompiles)."""

    coarse_res: float = 0.5
    sigma_coarse: float = 0.5
    yaw_step_deg: float = 5.0
    peaks_per_yaw: int = 6
    n_peaks: int = 24  # coarse peaks polished
    polish_points: int = 512  # points (and half as many free samples) used to polish
    n_out: int = 12  # placements returned
    sigma_fine: float = 0.12
    lam: float = 1.0
    nms_xy: float = 1.0
    nms_deg: float = 6.0


GRID_RES = 0.3  # m: the evidence grid's cell (``decision.grid``)


@dataclass(frozen=True)
class PlanFields:
    """The plan as the search reads it (pytree; padded to a bucket for shared compilation).

    Attributes:
        origin: ``(2,)`` fine grid lower-left corner (m); res: fine cell (m, static).
        dist: ``(H, W)`` distance to the nearest wall solid (m), for ray marching.
        hit: ``(H, W)`` fine wall-proximity field at ``sigma_fine``.
        bad: ``(H, W)`` fine obstacle field (1 in walls, ``outside`` outside the footprint).
        c_hit, c_bad: ``(Hc, Wc)`` the coarse fields; c_res: their cell (m, static): the fine
            cell times the block factor nearest to ``coarse_res``.
        outside: ``()`` the obstacle field off the grid (``Rasters.outside``).
        g_hit, g_free: ``(Hg, Wg)`` the evidence grid's fields (``decision.grid``): a
            return's and a free sample's log-likelihood (``path_llr``'s model), max-pooled
            over the reach of a grid cell (+-``g_res`` / 2, ``g_res`` the fine cell times the
            block factor nearest to ``GRID_RES``) and read at the cells' centres, less their
            values off the plan ``g_off`` ``(2,)`` (so the FFT's zero padding is "off the
            plan"); g_res: their cell (m, static).
    """

    origin: jax.Array
    dist: jax.Array
    hit: jax.Array
    bad: jax.Array
    c_hit: jax.Array
    c_bad: jax.Array
    outside: jax.Array
    g_hit: jax.Array
    g_free: jax.Array
    g_off: jax.Array
    res: float = 0.10
    c_res: float = 0.40
    g_res: float = 0.30


jax.tree_util.register_dataclass(
    PlanFields,
    data_fields=[
        "origin",
        "dist",
        "hit",
        "bad",
        "c_hit",
        "c_bad",
        "outside",
        "g_hit",
        "g_free",
        "g_off",
    ],
    meta_fields=["res", "c_res", "g_res"],
)


def plan_fields(rasters, params: SearchParams = SearchParams(), shape=None) -> PlanFields:
    """``PlanFields`` from ``Rasters`` (host); ``shape`` pads the fine grid to a bucket."""
    r = rasters.to_numpy()
    dist = np.asarray(r.dist, np.float64)
    out = float(r.outside)
    bad = np.where(np.asarray(r.wall), 1.0, np.where(np.asarray(r.inside), 0.0, out))
    h, w = dist.shape
    H, W = shape or (h, w)
    f = max(1, int(round(params.coarse_res / r.res)))
    H, W = -(-H // f) * f, -(-W // f) * f
    dist = np.pad(dist, ((0, H - h), (0, W - w)), constant_values=10.0)
    bad = np.pad(bad, ((0, H - h), (0, W - w)), constant_values=out)
    c_d = dist.reshape(H // f, f, W // f, f).min(axis=(1, 3))
    c_b = bad.reshape(H // f, f, W // f, f).mean(axis=(1, 3))
    fg = max(1, int(round(GRID_RES / r.res)))
    g_hit, g_free, g_off = _grid_fields(dist, bad, out, fg)
    return PlanFields(
        origin=np.asarray(r.origin, np.float32),
        dist=dist.astype(np.float32),
        hit=np.exp(-(dist**2) / (2 * params.sigma_fine**2)).astype(np.float32),
        bad=bad.astype(np.float32),
        c_hit=np.exp(-(c_d**2) / (2 * params.sigma_coarse**2)).astype(np.float32),
        c_bad=c_b.astype(np.float32),
        outside=np.float32(out),
        g_hit=g_hit,
        g_free=g_free,
        g_off=g_off,
        res=float(r.res),
        c_res=float(r.res * f),
        g_res=float(r.res * fg),
    )


def _grid_fields(dist, bad, out: float, f: int):
    """The evidence grid's fields (``PlanFields.g_hit``, ``g_free``, ``g_off``) from the fine
    distance and obstacle rasters, block factor ``f``."""
    from scipy import ndimage

    from mfcl_jax.frontend.path_llr import LLRParams

    p = LLRParams()
    hit = np.log((1.0 - p.z_rand) * np.exp(-(dist**2) / (2 * p.sigma**2)) + p.z_rand)
    free = np.log(1.0 - p.z_block * np.clip(bad, 0.0, 1.0))
    # the reach of a cell's placements: +-half its diagonal (a square, separable)
    k = 2 * int(math.ceil(f / 2.0 - 0.5)) + 1
    centres = np.arange(f // 2, dist.shape[0], f), np.arange(f // 2, dist.shape[1], f)
    off = np.asarray([math.log(p.z_rand), math.log(1.0 - p.z_block * min(max(out, 0.0), 1.0))])
    g = [ndimage.maximum_filter(a, size=k, mode="nearest")[np.ix_(*centres)] - o
         for a, o in zip((hit, free), off, strict=True)]  # fmt: skip
    return g[0].astype(np.float32), g[1].astype(np.float32), off.astype(np.float32)


def sample_field(field, origin, res, xy, fill):
    """Bilinear lookup of ``field (H, W)`` (lower-left corner ``origin``, cell ``res``) at
    ``xy (*, 2)``; neighbours off the grid read ``fill``."""
    u = (xy[..., 0] - origin[0]) / res - 0.5
    v = (xy[..., 1] - origin[1]) / res - 0.5
    field = jnp.asarray(field)
    h, w = field.shape
    u0, v0 = jnp.floor(u), jnp.floor(v)
    fu, fv = u - u0, v - v0
    u0, v0 = u0.astype(jnp.int32), v0.astype(jnp.int32)

    def at(iv, iu):
        ok = (iu >= 0) & (iu < w) & (iv >= 0) & (iv < h)
        val = field.reshape(-1).at[jnp.where(ok, iv * w + iu, 0)].get(mode="promise_in_bounds")
        return jnp.where(ok, val, fill)

    return (
        at(v0, u0) * (1 - fu) * (1 - fv)
        + at(v0, u0 + 1) * fu * (1 - fv)
        + at(v0 + 1, u0) * (1 - fu) * fv
        + at(v0 + 1, u0 + 1) * fu * fv
    )
