"""The floor plan as the front-end reads it: rasters, verification fields, wall corners and
the dense hypotheses' fields (``FloorplanFeatures``), built on the host and padded to shape
buckets so that buildings share a compilation."""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.floorplan.raster import Rasters, pad_to
from mfcl_jax.frontend import features, verify
from mfcl_jax.frontend.dense import DenseFields, dense_fields
from mfcl_jax.frontend.params import FrontendParams

__all__ = ["FloorplanFeatures", "build_features", "common_shape", "common_features"]


@dataclass(frozen=True)
class FloorplanFeatures:
    """Host-prepared plan features (a pytree of arrays).

    Attributes:
        rasters: ``Rasters`` (JAX arrays); grid geometry and the wall mask.
        sdf4: ``(H + 1, W + 1, 4)`` signed wall-surface distance, ``verify.stack4`` layout.
        pen4: ``(H + 1, W + 1, 4)`` free-space penalty field, same layout.
        corner_pos: ``(C, 2)``; corner_a1, corner_a2: ``(C,)`` edge angles (rad);
        corner_kind: ``(C,)`` int32; corner_valid: ``(C,)`` bool.
        dense: ``dense.DenseFields`` (the dense hypotheses' plan fields and wall directions).
    """

    rasters: Rasters
    sdf4: jax.Array
    pen4: jax.Array
    corner_pos: jax.Array
    corner_a1: jax.Array
    corner_a2: jax.Array
    corner_kind: jax.Array
    corner_valid: jax.Array
    dense: DenseFields

    @property
    def plan_corners(self) -> tuple:
        """``(pos, a1, a2, kind, valid)``, the plan side of the corner correspondences."""
        return (
            self.corner_pos,
            self.corner_a1,
            self.corner_a2,
            self.corner_kind,
            self.corner_valid,
        )


jax.tree_util.register_dataclass(
    FloorplanFeatures,
    data_fields=[
        "rasters",
        "sdf4",
        "pen4",
        "corner_pos",
        "corner_a1",
        "corner_a2",
        "corner_kind",
        "corner_valid",
        "dense",
    ],
    meta_fields=[],
)


def _pad_corners(corners, capacity: int):
    pos, a1, a2, kind, valid = (np.asarray(c) for c in corners)
    n = int(np.sum(valid)) if valid.size else 0
    if np.any(valid[n:]):
        raise ValueError("build_features: corners must be packed (valid ones first)")
    if n > capacity:
        raise ValueError(f"build_features: {n} corners exceed corner_capacity={capacity}")

    def fit(v, fill):
        out = np.full((capacity, *v.shape[1:]), fill, v.dtype)
        k = min(len(v), capacity)
        out[:k] = v[:k]
        return out

    return (
        fit(pos.reshape(-1, 2), 0),
        fit(a1.reshape(-1), 0),
        fit(a2.reshape(-1), 0),
        fit(kind.reshape(-1), 0),
        fit(valid.reshape(-1), False),
    )


def build_features(
    fp,
    params: FrontendParams = FrontendParams(),
    res: float = 0.10,
    rasters: Rasters | None = None,
    corners=None,
    shape=None,
    n_rooms: int | None = None,
    corner_capacity: int | None = None,
) -> FloorplanFeatures:
    """Builds ``FloorplanFeatures`` from a ``Floorplan`` (or from given rasters + corners).

    Args:
        fp: a ``Floorplan``, or None when ``rasters`` and ``corners`` are given (the signed
            distance is then raster-based, accurate to half a cell).
        params: front-end parameters (kernel widths).
        res: raster resolution (m).
        rasters: optional precomputed (possibly padded, see ``raster.pad_to``) rasters.
        corners: optional ``(pos, a1, a2, kind, valid)`` as from ``features.floorplan_corners``.
        shape: optional ``(H, W)`` raster bucket to pad to (``raster.pad_to``), with
            ``n_rooms`` rooms; buildings with equal buckets share one compilation.
        corner_capacity: optional padded corner count (same purpose).
    """
    if rasters is None:
        if fp is None:
            raise ValueError("build_features: need a Floorplan or rasters + corners")
        rasters = fp.rasterize(res=res)
    if corners is None:
        if fp is None:
            raise ValueError("build_features: need a Floorplan or rasters + corners")
        corners = features.floorplan_corners(fp, capacity=corner_capacity)
    rasters = rasters.to_numpy()
    if shape is not None or n_rooms is not None:
        rasters = pad_to(rasters, tuple(shape or rasters.shape), n_rooms)
    if corner_capacity is not None:
        corners = _pad_corners(corners, corner_capacity)
    sdf, pen = verify.surface_fields(fp, rasters, params.sigma_free)
    pos, a1, a2, kind, valid = (np.asarray(c) for c in corners)
    return FloorplanFeatures(
        rasters=rasters.to_jax(),
        sdf4=jnp.asarray(verify.stack4(sdf, verify.FAR)),
        pen4=jnp.asarray(verify.stack4(pen, float(rasters.outside))),
        corner_pos=jnp.asarray(pos, jnp.float32).reshape(-1, 2),
        corner_a1=jnp.asarray(a1, jnp.float32).reshape(-1),
        corner_a2=jnp.asarray(a2, jnp.float32).reshape(-1),
        corner_kind=jnp.asarray(kind, jnp.int32).reshape(-1),
        corner_valid=jnp.asarray(valid, bool).reshape(-1),
        dense=dense_fields(rasters, a1, a2, valid, params),
    )


def common_shape(floorplans, res: float = 0.10, multiple: int = 64, margin: float = 1.0) -> dict:
    """The one shape bucket that fits every floor plan's features.

    Raster sides and the corner capacity are rounded up to a multiple of ``multiple``; the
    raster sides follow ``Floorplan.rasterize`` (``margin`` m around the bounds).

    Returns:
        ``build_features`` keyword arguments ``res, shape, n_rooms, corner_capacity``.
    """
    fps = list(floorplans)
    if not fps:
        raise ValueError("common_shape: no floor plans given")
    up = lambda n: max(multiple, -(-n // multiple) * multiple)  # noqa: E731

    def side(lo, hi):
        return int(math.ceil((hi + margin - (lo - margin)) / res))

    h = max(side(fp.bounds[1], fp.bounds[3]) for fp in fps)
    w = max(side(fp.bounds[0], fp.bounds[2]) for fp in fps)
    return dict(
        res=res,
        shape=(up(h), up(w)),
        n_rooms=max(len(fp.rooms) for fp in fps),
        corner_capacity=up(max(len(fp.corners[0]) for fp in fps)),
    )


def common_features(
    floorplans, params: FrontendParams = FrontendParams(), res: float = 0.10, multiple: int = 64
) -> list[FloorplanFeatures]:
    """Features of several buildings padded to one shape bucket (one compilation for all)."""
    fps = list(floorplans)
    kw = common_shape(fps, res, multiple)
    return [build_features(fp, params, **kw) for fp in fps]
