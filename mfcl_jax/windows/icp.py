"""The LiDAR odometry's settings and matching kernel: one scan against a local map of points
and normals (point-to-line ICP with a small point-to-point share, Geman-McClure weights, a
prior that ties the pose to its prediction, a degeneracy-aware update). ``odometry`` runs it
per keyframe."""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.arg_reduce import argmin

__all__ = ["ScanMatchParams", "thin_scan", "thresholds", "normals", "icp"]


@dataclass(frozen=True)
class ScanMatchParams:
    """LiDAR odometry settings.

    Attributes:
        enabled: refine the odometry (``False``: windows use the input odometry as it is).
        points: points kept per keyframe scan (static shape).
        map_scans: keyframes in the local map (static shape).
        voxel: thinning voxel (m) before the points are subsampled.
        max_range: returns farther than this (m) are dropped.
        iters: Gauss-Newton iterations.
        gate: correspondences farther than this (m) are ignored.
        sigma: Geman-McClure kernel width (m); also the inlier distance.
        point_std: per-point residual std (m) against which the prior is weighed.
        point_weight: share of the point-to-point residual next to the point-to-line one.
        normal_radius: neighbourhood (m) of a map point's normal.
        degenerate: a translation direction whose information from the points is below this
            share of the points' total weight is left to the prior (degeneracy-aware ICP).
        min_gain: the match replaces the prediction only when it lowers the scan's mean
            squared misfit by more than ``min_gain`` squared (m).
        prior_xy, prior_yaw_deg: std of the input odometry's increment error per keyframe.
        min_inliers: fewest inliers for a match to be trusted.
        max_shift, max_turn_deg: largest trusted correction of the prediction.
        jump_fit: mean squared misfit (m^2, capped at ``gate``) above which the input's
            increment is put to the jump test, and under which an alternative must fit.
        jump_ratio: how many times better than the input's an alternative must fit.
        chunk: keyframes per kernel call (static shape).
    """

    enabled: bool = True
    points: int = 128
    map_scans: int = 10
    voxel: float = 0.15
    max_range: float = 20.0
    iters: int = 8
    gate: float = 0.6
    sigma: float = 0.20
    point_std: float = 0.05
    point_weight: float = 0.01
    degenerate: float = 0.05
    min_gain: float = 0.02
    normal_radius: float = 0.5
    prior_xy: float = 0.05
    prior_yaw_deg: float = 2.0
    min_inliers: int = 24
    max_shift: float = 0.5
    max_turn_deg: float = 10.0
    jump_fit: float = 0.02
    jump_ratio: float = 3.0
    chunk: int = 32

    def __post_init__(self):
        for name in ("points", "map_scans", "iters", "chunk", "min_inliers"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v > 0):
                raise ValueError(f"ScanMatchParams: {name} must be a positive int, got {v!r}")
        for name in ("voxel", "max_range", "gate", "sigma", "point_std", "point_weight",
                     "normal_radius", "degenerate", "min_gain", "prior_xy", "prior_yaw_deg",
                     "max_shift", "max_turn_deg", "jump_fit", "jump_ratio"):  # fmt: skip
            v = getattr(self, name)
            if not (isinstance(v, int | float) and v > 0):
                raise ValueError(f"ScanMatchParams: {name} must be > 0, got {name}={v!r}")


def thin_scan(scan, p: ScanMatchParams) -> tuple[np.ndarray, np.ndarray]:
    """One scan ``(n, 2)`` (sensor frame, NaN allowed) as ``(points (P, 2), mask (P,))``:
    finite returns within ``max_range``, one per ``voxel``, evenly subsampled to ``P``."""
    s = np.asarray(scan, np.float64).reshape(-1, 2)
    r2 = np.einsum("ij,ij->i", s, s)
    s = s[np.all(np.isfinite(s), axis=1) & (r2 <= p.max_range**2) & (r2 > 1e-4)]
    if len(s):
        cell = np.floor(s / p.voxel).astype(np.int64)  # within max_range: |cell| < 2^20
        code = (cell[:, 0] + (1 << 20)) * (1 << 21) + (cell[:, 1] + (1 << 20))
        _, first = np.unique(code, return_index=True)  # one int64 per cell: a 1-D sort
        s = s[np.sort(first)]
    if len(s) > p.points:
        s = s[np.linspace(0, len(s) - 1, p.points).round().astype(int)]
    out = np.zeros((p.points, 2), np.float32)
    mask = np.zeros(p.points, bool)
    out[: len(s)], mask[: len(s)] = s, True
    return out, mask


def thresholds(p: ScanMatchParams) -> dict:
    f = np.float32
    return dict(
        iters=np.int32(p.iters),
        gate=f(p.gate),
        sigma=f(p.sigma),
        point_std=f(p.point_std),
        point_weight=f(p.point_weight),
        normal_radius=f(p.normal_radius),
        degenerate=f(p.degenerate),
        min_gain=f(p.min_gain),
        prior_xy=f(p.prior_xy),
        prior_yaw=f(np.deg2rad(p.prior_yaw_deg)),
        min_inliers=np.int32(p.min_inliers),
        max_shift=f(p.max_shift),
        max_turn=f(np.deg2rad(p.max_turn_deg)),
        jump_fit=f(p.jump_fit),
        jump_ratio=f(p.jump_ratio),
    )


def normals(scan, smask, radius):
    """Unit normals ``(P, 2)`` of a scan's points from the points within ``radius`` (the
    principal axis of their scatter); zero where fewer than 3 points or no line shape."""
    d2 = jnp.sum((scan[:, None, :] - scan[None, :, :]) ** 2, axis=-1)
    a = (smask[:, None] & smask[None, :] & (d2 < radius**2)).astype(scan.dtype)
    n = jnp.sum(a, 1)
    mu = (a @ scan) / jnp.maximum(n, 1.0)[:, None]
    dx = scan[None, :, :] - mu[:, None, :]  # (P, P, 2)
    c = jnp.einsum("ij,ijk,ijl->ikl", a, dx, dx) / jnp.maximum(n, 1.0)[:, None, None]
    cxx, cxy, cyy = c[:, 0, 0], c[:, 0, 1], c[:, 1, 1]
    theta = 0.5 * jnp.arctan2(2 * cxy, cxx - cyy)  # the line's direction
    half = 0.5 * (cxx + cyy)
    disc = jnp.sqrt(jnp.maximum(half**2 - (cxx * cyy - cxy**2), 0.0))
    line = (half - disc) <= 0.1 * (half + disc)
    ok = smask & (n >= 3) & line
    nrm = jnp.stack([-jnp.sin(theta), jnp.cos(theta)], -1)
    return jnp.where(ok[:, None], nrm, 0.0)


def icp(pred, scan, smask, mpts, mnrm, mmask, th):
    """Refines ``pred (3,)`` so that ``scan (P, 2)`` fits the map ``mpts (Q, 2)`` (normals
    ``mnrm (Q, 2)``, zero where none): point-to-line residuals, plus a small point-to-point
    share (``point_weight``) that holds points without a normal and the sliding directions.

    Returns ``(pose (3,), inliers ())``."""
    big = jnp.asarray(1e6, mpts.dtype)
    mp = jnp.where(mmask[:, None], mpts, big)
    info_prior = jnp.stack([1 / th["prior_xy"] ** 2] * 2 + [1 / th["prior_yaw"] ** 2])
    w_pt = 1 / th["point_std"] ** 2

    def nearest(pose):
        q = se2.apply(pose, scan)  # (P, 2)
        # The (P, Q) table is the kernel's whole cost. Differences, not the matrix-product
        # expansion: exact to the last bit whatever the batch (a product's rounding follows
        # the batch size's kernel), and no cancellation.
        d2 = (q[:, None, 0] - mp[None, :, 0]) ** 2 + (q[:, None, 1] - mp[None, :, 1]) ** 2
        j = argmin(d2, axis=1)  # two plain reductions, not jnp.argmin's scalar loop
        m = mp[j]
        return q, m, mnrm[j], jnp.sum((q - m) ** 2, axis=1)

    def body(_, pose):
        q, m, nn, d2 = nearest(pose)
        s2 = th["sigma"] ** 2
        w = jnp.where(smask & (d2 < th["gate"] ** 2), (s2 / (s2 + d2)) ** 2, 0.0) * w_pt
        r = q - m  # (P, 2)
        lever = q - pose[:2]
        # d q / d (tx, ty, dtheta), the rotation taken about the sensor origin.
        jx = jnp.stack([jnp.ones_like(w), jnp.zeros_like(w), -lever[:, 1]], -1)
        jy = jnp.stack([jnp.zeros_like(w), jnp.ones_like(w), lever[:, 0]], -1)
        jl = nn[:, :1] * jx + nn[:, 1:] * jy  # (P, 3) of the residual along the normal
        rl = jnp.sum(nn * r, 1)
        wp = w * th["point_weight"]
        H = (
            jnp.einsum("p,pi,pj->ij", w, jl, jl)
            + jnp.einsum("p,pi,pj->ij", wp, jx, jx)
            + jnp.einsum("p,pi,pj->ij", wp, jy, jy)
        )
        g = (
            jnp.einsum("p,pi,p->i", w, jl, rl)
            + jnp.einsum("p,pi,p->i", wp, jx, r[:, 0])
            + jnp.einsum("p,pi,p->i", wp, jy, r[:, 1])
        )
        # Translations the scans barely constrain (along a bare corridor: the few normals that
        # are not square to the walls) are left to the prior, i.e. to the input odometry's
        # increment; otherwise those few points would drag the pose along the corridor.
        lam, vec = jnp.linalg.eigh(H[:2, :2])
        keep = lam > th["degenerate"] * jnp.maximum(jnp.sum(w), 1e-9)
        proj = jnp.eye(3, dtype=H.dtype).at[:2, :2].set((vec * keep.astype(H.dtype)) @ vec.T)
        H = proj @ H @ proj
        g = proj @ g
        e = jnp.concatenate([pose[:2] - pred[:2], se2.angle_diff(pose[2:], pred[2:])])
        H = H + jnp.diag(info_prior)
        g = g + info_prior * e
        delta = -jnp.linalg.solve(H, g)
        return jnp.concatenate([pose[:2] + delta[:2], se2.wrap(pose[2:] + delta[2:])])

    def misfit(pose):
        """Mean squared distance along the normals (point distance where none), capped at
        the gate: how badly the scan at ``pose`` fits the map."""
        q, m, nn, d2 = nearest(pose)
        has = jnp.sum(nn * nn, 1) > 0
        r2 = jnp.where(has, jnp.sum(nn * (q - m), 1) ** 2, d2)
        r2 = jnp.minimum(r2, th["gate"] ** 2)
        n = jnp.maximum(jnp.sum(smask).astype(r2.dtype), 1.0)
        return jnp.sum(jnp.where(smask, r2, 0.0)) / n, d2

    pose = jax.lax.fori_loop(0, th["iters"], body, pred)
    after, d2 = misfit(pose)
    before, _ = misfit(pred)
    inliers = jnp.sum(smask & (d2 < th["sigma"] ** 2))
    # The input's increment stands unless the scans clearly fit better elsewhere: a good
    # odometry (an LIO's) is then kept as it is, not replaced by the matcher's own noise.
    better = before - after > th["min_gain"] ** 2
    return jnp.where(better, pose, pred), inliers, jnp.where(better, after, before)
