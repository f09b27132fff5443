"""Rivals of a commit: where else could the whole path seen so far lie in the building?

The probe synthesises aliases from the building's congruent rooms and rotational
self-motions; the certification also weighs the other consensus groups and each window's
runner-up. None of these is a global view of the path: a half-turn of a long corridor in an
occupancy map, or a wing mirrored about an axis, is none of them. So, at a window where the
layer is about to commit, the accumulated path (the history's evidence samples, placed by
odometry: what the layer already sees) is searched over every rigid placement in the plan
(``frontend.path_search``: exhaustive over headings and translations, then polished), and
the best placements become rivals of ``T*`` in the certification from that window on
(``certify``: a rival is ruled out only when some window contradicts it and none favours it).

Everything here is a kernel: the layer runs it inside its ``update`` through ``sparse_cond``,
so a batch pays for the searches its runs make, not for one per window.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.frontend import path_search as ps

__all__ = [
    "RivalParams",
    "DEFAULT_RIVALS",
    "RIVAL_SLOTS",
    "path_cloud",
    "search",
    "rival_fields",
    "stack_fields",
    "image_size",
]


@dataclass(frozen=True)
class RivalParams:
    """Settings of the rival search (fixed once for every building; static)."""

    n_rivals: int = 6  # best distinct placements kept per search
    max_searches: int = 3  # searches per run (each at a window about to commit)
    ray_fracs: tuple = (0.3, 0.6, 0.85)  # free samples along each evidence ray
    max_points: int = 2048
    max_free: int = 2048
    keep_ratio: float = 0.5  # placements scoring below this share of the best are dropped
    search: ps.SearchParams = ps.SearchParams()


DEFAULT_RIVALS = RivalParams()
RIVAL_SLOTS = DEFAULT_RIVALS.n_rivals * DEFAULT_RIVALS.max_searches  # static rival capacity


def _even(mask, n: int):
    """Indices ``(n,)`` of up to ``n`` entries of ``mask``, evenly spread over its true
    entries in order, and their validity."""
    m = mask.shape[0]
    order = jnp.argsort(~mask, stable=True)  # true entries first, in order
    count = jnp.sum(mask)
    i = jnp.arange(n)
    spread = i.astype(jnp.float32) * (count - 1).astype(jnp.float32) / max(n - 1, 1)
    pos = jnp.where(count > n, jnp.round(spread).astype(jnp.int32), i)
    return order[jnp.clip(pos, 0, m - 1)], i < count


def path_cloud(ev_points, ev_origins, ev_mask, X, p: RivalParams = DEFAULT_RIVALS):
    """The path seen so far in the odometry frame, subsampled to fixed sizes.

    Args:
        ev_points, ev_origins: ``(C, P, 2)`` evidence sample of each window, in its frame;
        ev_mask: ``(C, P)`` (false on windows outside the prefix); X: ``(C, 3)``.

    Returns:
        ``(points (max_points, 2), ok, free (max_free, 2), ok)``: returns, and free-space
        samples along the rays and at the (distinct, to a centimetre) sensor positions. A scan
        seen by several windows weighs more, as it would in any accumulated map.
    """
    q = se2.apply(X, ev_points).reshape(-1, 2)
    o = se2.apply(X, ev_origins).reshape(-1, 2)
    m = ev_mask.reshape(-1)
    fr = jnp.asarray(p.ray_fracs, q.dtype)[:, None, None]
    along = (o[None] + fr * (q - o)[None]).reshape(-1, 2)
    along_ok = jnp.tile(m, len(p.ray_fracs))
    code = jnp.round(o * 100.0).astype(jnp.int32)
    order = jnp.lexsort((code[:, 1], code[:, 0], ~m))
    sc = code[order]
    first = jnp.concatenate([jnp.ones(1, bool), jnp.any(sc[1:] != sc[:-1], axis=1)])
    sensor_ok = jnp.zeros_like(m).at[order].set(first & m[order])
    free = jnp.concatenate([along, o])
    free_ok = jnp.concatenate([along_ok, sensor_ok])
    ip, pok = _even(m, p.max_points)
    jf, fok = _even(free_ok, p.max_free)
    return q[ip], pok, free[jf], fok


def search(ev_points, ev_origins, ev_mask, X, fields: ps.PlanFields, n_img: int,
           p: RivalParams = DEFAULT_RIVALS):  # fmt: skip
    """The best rigid placements of the path (``path_cloud``) in the plan.

    Returns:
        ``(anchors (n_rivals, 3), ok (n_rivals,))``, best first: each anchor maps ``L`` into
        the plan frame like ``T*`` does.
    """
    pts, pok, free, fok = path_cloud(ev_points, ev_origins, ev_mask, X, p)
    w = pok.astype(pts.dtype)
    c = jnp.sum(pts * w[:, None], 0) / jnp.maximum(jnp.sum(w), 1.0)
    g, sc = ps.search(pts - c, pok, free - c, fok, fields, p.search, n_img)
    good = jnp.isfinite(sc)
    best = jnp.max(jnp.where(good, sc, -jnp.inf))
    good &= sc >= p.keep_ratio * best
    g, good = g[: p.n_rivals], good[: p.n_rivals]  # sorted best first (path_search.nms)
    cg, sg = jnp.cos(g[:, 2]), jnp.sin(g[:, 2])
    anchors = jnp.stack([g[:, 0] - (cg * c[0] - sg * c[1]), g[:, 1] - (sg * c[0] + cg * c[1]),
                         g[:, 2]], 1)  # fmt: skip
    return jnp.where(good[:, None], anchors, 0.0), good & jnp.any(pok)


def rival_fields(source, p: RivalParams = DEFAULT_RIVALS, shape=None) -> ps.PlanFields:
    """The search's ``PlanFields`` of a ``Floorplan`` or ``Rasters`` (host), padded to a
    bucket of 256 cells (or to ``shape``) so that buildings share compilations."""
    from mfcl_jax.floorplan.raster import Rasters

    r = source if isinstance(source, Rasters) else source.rasterize()
    if shape is None:
        shape = tuple(-(-n // 256) * 256 for n in r.shape)
    return ps.plan_fields(r, p.search, shape=shape)


def stack_fields(sources, p: RivalParams = DEFAULT_RIVALS) -> ps.PlanFields:
    """``PlanFields`` of several buildings on one bucket, stacked ``(B, ...)`` (host)."""
    from mfcl_jax.floorplan.raster import Rasters

    rs = [s if isinstance(s, Rasters) else s.rasterize() for s in sources]
    shape = tuple(-(-max(r.shape[i] for r in rs) // 256) * 256 for i in range(2))
    fs = [ps.plan_fields(r, p.search, shape=shape) for r in rs]
    return jax.tree.map(lambda *xs: np.stack(xs), *fs)


def image_size(sources, p: RivalParams = DEFAULT_RIVALS) -> int:
    """Static side (coarse cells) of the path image for plans ``sources`` (``Floorplan`` or
    ``Rasters``): the larger plan side plus 2 m, in multiples of 128. The path is centred on
    its mean, so a path that spans the whole plan stays inside; only a lopsided one (most of
    it at one end, a little at the far end) loses its far points to the image border."""
    from mfcl_jax.floorplan.raster import Rasters

    rs = [s if isinstance(s, Rasters) else s.rasterize() for s in sources]
    side = max(max(r.shape) * r.res for r in rs)
    c_res = max(1, round(p.search.coarse_res / rs[0].res)) * rs[0].res
    return int(-(-((side + 2.0) / c_res) // 128) * 128)
