"""Per-scan statistics of given placements of a path in the plan (the scorer's evidence).

Under each placement ``g: F -> B``: how close each scan's points lie to plan walls, what share
of its rays pass through plan walls (sphere tracing on the distance field), and whether the
sensor stands in a wall or outside the building. Read on ``path_fields.PlanFields``.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.frontend.path_fields import PlanFields, sample_field

__all__ = ["evaluate_placements"]


def _through(o, pts, ok, fields, margin, steps):
    """Whether each ray ``o -> pts`` meets a plan wall more than ``margin`` m before its end
    (sphere tracing on the distance field: a measured return from behind a solid wall)."""
    d = pts - o
    r = jnp.linalg.norm(d, axis=-1)
    u = d / jnp.maximum(r, 1e-6)[..., None]

    def body(_, carry):
        t, hit = carry
        x = o + t[..., None] * u
        dd = sample_field(fields.dist, fields.origin, fields.res, x, 10.0)
        hit = hit | ((dd < 0.02) & (t < r - margin))
        return t + jnp.maximum(dd, 0.04), hit

    t0 = jnp.full(r.shape, 0.05, r.dtype)
    _, hit = jax.lax.fori_loop(0, steps, body, (t0, jnp.zeros(r.shape, bool)))
    return hit & ok


@partial(jax.jit, static_argnames=("steps",))
def evaluate_placements(g, scan_pts, scan_ok, sensor, fields: PlanFields, margin=0.5, steps=24):
    """Per-scan statistics of placements.

    Args:
        g: ``(G, 3)`` placements of frame ``F`` into B.
        scan_pts: ``(S, B, 2)`` scan points in ``F``; scan_ok: ``(S, B)``.
        sensor: ``(S, 2)`` sensor positions in ``F``.
        fields: ``PlanFields``.
        margin: a ray meeting a wall this far (m) before its end point passes through it.
        steps: sphere-tracing iterations (static).

    Returns:
        ``(hit (G, S), through (G, S), pose_bad (G, S))``: mean wall proximity of each scan's
        points, the share of its rays that pass through plan walls, and the obstacle value
        (wall or outside the building) at the sensor position, under each placement.
    """

    def one(gi):
        p = se2.apply(gi, scan_pts)
        o = se2.apply(gi, sensor[:, None, :])  # (S, 1, 2)
        h = sample_field(fields.hit, fields.origin, fields.res, p, 0.0)
        n = jnp.maximum(jnp.sum(scan_ok, -1), 1).astype(jnp.float32)
        mh = jnp.sum(jnp.where(scan_ok, h, 0.0), -1) / n
        th = jnp.sum(_through(o, p, scan_ok, fields, margin, steps), -1).astype(n.dtype) / n
        pb = sample_field(fields.bad, fields.origin, fields.res, o[:, 0], fields.outside)
        return mh, th, pb

    return jax.lax.map(one, g)
