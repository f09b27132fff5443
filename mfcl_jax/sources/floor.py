"""Horizontal planes in a 3-D LiDAR cloud: the floor below the sensor and the ceiling above.

The floor is the lowest dense horizontal layer of the points below the sensor. Two facts of
ring LiDARs shape the detector. (1) Beams are spread evenly in angle, so a far surface gets few
points: heights are histogrammed with each point weighted by its squared horizontal range,
proportional to the surface it stands for (``_area``). The floor is only visible beyond
``height / tan(-lowest elevation)`` (4.1 m for a Mid-360 at 0.5 m), the bottoms of nearer walls
are not, so the weight makes a wide floor outweigh the dense wall bottoms. (2) One ring hitting
the walls of a room all round draws a near-horizontal "layer" too; it is not a plane, and it
lies above the floor, never under it.

Host NumPy: runs once per cloud (a few ms for 20 000 points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mfcl_jax.io.errors import DataError

__all__ = ["PlaneParams", "Plane", "detect_floor", "detect_ceiling", "level_rotation", "rowwise"]


@dataclass(frozen=True)
class PlaneParams:
    """Settings of the floor and ceiling detectors.

    Attributes:
        max_tilt_deg: the floor's normal may lean this far from +z (deg).
        layer: thickness of a histogram layer (m); the floor fit's first inlier band.
        dense: a layer is dense when it holds this fraction of the heaviest layer's weight.
        min_points: fewest points a floor (within ``layer / 4`` of it) or ceiling must hold.
    """

    max_tilt_deg: float = 10.0
    layer: float = 0.05
    dense: float = 0.25
    min_points: int = 60

    def __post_init__(self):
        if not (0 < self.max_tilt_deg < 45 and self.layer > 0 and 0 < self.dense <= 1):
            raise DataError(
                f"PlaneParams: need 0 < max_tilt_deg < 45, layer > 0, 0 < dense <= 1; got "
                f"max_tilt_deg={self.max_tilt_deg!r}, layer={self.layer!r}, dense={self.dense!r}"
            )
        if not self.min_points >= 3:
            raise DataError(f"PlaneParams.min_points must be >= 3, got {self.min_points!r}")


@dataclass(frozen=True)
class Plane:
    """A horizontal-ish plane ``{p : normal . p = -height}`` below the frame origin.

    Attributes:
        normal: ``(3,)`` unit normal, pointing up (+z side).
        height: height of the frame origin above the plane (m).
        n_points: points supporting it.
    """

    normal: np.ndarray
    height: float
    n_points: int

    @property
    def tilt_deg(self) -> float:
        return float(np.rad2deg(np.arccos(np.clip(self.normal[2], -1.0, 1.0))))


def rowwise(p: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``m`` applied to every row of ``p (n, 3)``: ``(n, k)`` for ``m (k, 3)``, ``(n,)`` for
    ``m (3,)``. einsum, not ``@``: a BLAS call for these thin products is slower by 10x when
    its threads compete for busy cores."""
    return np.einsum("...k,nk->n...", m, p)


def _layers(h: np.ndarray, w: np.ndarray, layer: float):
    """Weights ``w (n,)`` of points at heights ``h (G, n)`` in half-layer bins and in
    half-overlapping layers ``[lo + i layer/2, lo + (i + 2) layer/2)`` (a peak split by a bin
    edge still counts whole). Returns ``(bins (G, nb), layers (G, nb - 1), lo)``."""
    half = layer / 2
    lo = float(h.min())
    idx = np.floor((h - lo) / half).astype(np.int64)
    nb = int(idx.max()) + 2
    rows = np.arange(h.shape[0])[:, None] * nb
    ww = np.broadcast_to(w, h.shape).ravel()
    c = np.bincount((rows + idx).ravel(), ww, minlength=h.shape[0] * nb).reshape(-1, nb)
    return c, c[:, :-1] + c[:, 1:], lo


def _area(p: np.ndarray) -> np.ndarray:
    """Weight of each point ``(n,)``: its squared horizontal range. A LiDAR samples evenly in
    angle, so this is proportional to the surface a return stands for; it lets a wide floor
    (beyond ``height / tan(-lowest elevation)``) outweigh the dense bottoms of nearby walls."""
    return p[:, 0] ** 2 + p[:, 1] ** 2


def detect_floor(points, params: PlaneParams = PlaneParams(), below: float = 0.2):
    """The floor: the lowest dense horizontal layer below the frame origin.

    Histograms of heights along candidate up directions are weighted by ``_area``; a layer is
    dense when it holds ``dense`` of the heaviest layer over all directions. The directions
    form a grid of tilts (2 deg steps up to ``max_tilt_deg``, then 0.5 deg steps around the
    best); the best one puts the most weight into its lowest dense layer and the least under
    it (along a wrong one the floor smears over many layers, its low tail under the rest); a
    weighted least-squares plane through that layer's points refines it.

    Args:
        points: ``(n, 3)`` finite points (sensor or base frame, z roughly up).
        params: the detector's settings.
        below: only points this far below the origin are floor candidates (m).

    Returns:
        A ``Plane``, or ``None`` when no layer of ``min_points`` exists below the origin.
    """
    p = np.asarray(points, np.float64)
    p = p[p[:, 2] < -below]
    if len(p) < params.min_points:
        return None
    w = _area(p)
    sub = slice(None, None, max(1, len(p) // 2000))  # the direction search needs no more
    best = np.zeros(2)
    for step, half in ((2.0, params.max_tilt_deg), (0.5, 1.5)):
        off = np.deg2rad(np.arange(-half, half + 1e-9, step))
        tx, ty = np.meshgrid(off + best[0], off + best[1], indexing="ij")
        ups = np.stack([np.tan(tx).ravel(), np.tan(ty).ravel(), np.ones(tx.size)], 1)
        ups /= np.linalg.norm(ups, axis=1, keepdims=True)
        bins, sums, lo = _layers(rowwise(p[sub], ups).T, w[sub], params.layer)
        dense = sums >= params.dense * sums.max()
        first = np.argmax(dense, axis=1)  # the lowest dense layer of every direction ...
        cols = np.arange(sums.shape[1])
        top = np.append(sums[:, 1:] < sums[:, :-1], np.ones((len(sums), 1), bool), 1)
        peak = np.argmax(top & (cols >= first[:, None]), axis=1)  # ... and the peak it climbs
        rows = np.arange(len(sums))
        # Nothing lies under a floor: the weight under a direction's lowest dense layer (the
        # low tail of a floor smeared by a wrong direction) counts against it.
        under = np.cumsum(bins, 1) - bins
        score = np.where(dense.any(1), sums[rows, peak] - under[rows, first], -np.inf)
        g = int(np.argmax(score))
        best = np.array([tx.ravel()[g], ty.ravel()[g]])
    level = lo + (peak[g] + 1) * params.layer / 2
    n = ups[g]
    # Refine: weighted least-squares planes through a shrinking band around the layer (a
    # floor is flat to a few mm; the bottoms of walls that share its layer are not).
    for tol in (params.layer, params.layer / 2, params.layer / 4):
        inl = np.abs(rowwise(p, n) - level) < tol
        if inl.sum() < max(3, params.min_points):
            return None
        q, wq = p[inl], np.sqrt(w[inl])[:, None]
        c = np.sum(q * wq**2, 0) / np.sum(wq**2)
        _, sv, vt = np.linalg.svd((q - c) * wq, full_matrices=False)
        cand = vt[2] * np.sign(vt[2, 2])
        # Collinear support (a floor seen along one line) fixes no plane: keep the direction.
        if sv[1] < 1e-3 * sv[0] or np.rad2deg(np.arccos(min(cand[2], 1.0))) > params.max_tilt_deg:
            cand = n
        n, level = cand, float(c @ cand)
    inl = int(np.sum(np.abs(rowwise(p, n) - level) < params.layer / 4))
    if -level < below or inl < params.min_points:
        return None
    return Plane(normal=n, height=-float(level), n_points=inl)


def level_rotation(n: np.ndarray) -> np.ndarray:
    """The rotation ``(3, 3)`` taking unit ``n`` to +z about a horizontal axis."""
    z = np.array([0.0, 0.0, 1.0])
    k = np.cross(n, z)
    s, c = np.linalg.norm(k), float(n @ z)
    if s < 1e-12:
        return np.eye(3)
    k = k / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def detect_ceiling(
    p: np.ndarray, up: np.ndarray, origin_up: float, params: PlaneParams = PlaneParams()
):
    """The highest dense (``_area``-weighted) layer of heights ``up`` more than 0.2 m above
    ``origin_up``, or ``None``."""
    sel = up > origin_up + 0.2
    if sel.sum() < params.min_points:
        return None
    _, sums, lo = _layers(up[sel][None], _area(p[sel]), params.layer)
    dense = np.flatnonzero(sums[0] >= params.dense * sums[0].max())
    return float(lo + (dense[-1] + 1) * params.layer / 2)
