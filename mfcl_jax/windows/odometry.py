"""LiDAR odometry: each keyframe's pose refined by ICP against a local map of the last ones.

Submaps are built by stacking a window's scans at their odometry poses, so the odometry's error
inside a window distorts the submap. Wheel odometry of a real robot turns a few degrees off in
a few metres (the raw Intel bag: with its ``/odom`` the front-end's best candidate was right in
14 % of the windows, with the true poses in 78 %). A LiDAR-inertial odometry, which the layer
assumes, does not; so the windows first re-estimate every keyframe's pose from the scans
themselves, as kiss-icp does in 3-D:

1. the prediction is the previous refined pose moved by the input odometry's increment;
2. point-to-point ICP of the keyframe's scan (thinned to ``points``) against the points of the
   last ``map_scans`` keyframes, each placed at its refined pose: nearest neighbours by brute
   force inside a ``gate``, Geman-McClure weights of width ``sigma``, Gauss-Newton steps with a
   prior that ties the pose to the prediction (``prior_xy``, ``prior_yaw_deg``), so a direction
   the scans cannot fix (along a featureless corridor) follows the input odometry;
3. a match with fewer than ``min_inliers`` points within ``sigma``, or one that moves the pose
   farther from the prediction than ``max_shift``/``max_turn_deg``, is not trusted: the pose is
   the prediction;
4. an odometry jump (``windows.odometry_segments``) starts over: the keyframe keeps its input
   pose and the local map is emptied, so the jump stays visible downstream;
5. the jump test finds the jumps the input's step does not show (an odometry restart near
   where its frame began: a 1 m step with a half turn): where the scan at the input's increment
   fits the local map poorly (mean squared misfit over ``jump_fit``), it is matched again from
   two predictions that ignore the input (the robot kept moving as it was; it stood still);
   a trusted match that fits well (misfit at most ``jump_fit``), ``jump_ratio`` times better
   than the input's, and farther from it than ``max_shift``/``max_turn_deg``, is a jump: the
   keyframe starts a new odometry segment (``Odometer.segments``) as in 4.

The refined odometry starts at the input's first pose and is causal: keyframe ``m`` depends on
keyframes ``0..m`` only, so a prefix's poses are the whole sequence's first poses. Input is
scans and odometry only. The kernel is one ``lax.scan`` over a chunk of ``chunk`` keyframes
(padded and masked), jitted once per parameter set; the host feeds chunks in order.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.sparse_cond import sparse_cond

__all__ = ["ScanMatchParams", "Odometer", "extend_many", "scan_match", "thin_scan"]


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
        cell = np.floor(s / p.voxel).astype(np.int64)
        _, first = np.unique(cell, axis=0, return_index=True)
        s = s[np.sort(first)]
    if len(s) > p.points:
        s = s[np.linspace(0, len(s) - 1, p.points).round().astype(int)]
    out = np.zeros((p.points, 2), np.float32)
    mask = np.zeros(p.points, bool)
    out[: len(s)], mask[: len(s)] = s, True
    return out, mask


def _normals(scan, smask, radius):
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


def _icp(pred, scan, smask, mpts, mnrm, mmask, th):
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
        j = jnp.argmin(d2, axis=1)
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


def _alternatives(ops):
    """The jump test's two matches that ignore the input (module doc, step 5)."""
    prev, prev_inc, pred, scan, smask, flat, th = ops
    best_pose, best_fit = pred, jnp.asarray(jnp.inf, pred.dtype)
    for guess in (se2.compose(prev, prev_inc), prev):  # kept moving as it was; stood still
        p2, i2, f2 = _icp(guess, scan, smask, *flat, th)
        ok = (i2 >= th["min_inliers"]) & _near(p2, guess, th) & jnp.all(jnp.isfinite(p2))
        take = ok & (f2 < best_fit)
        best_pose, best_fit = jnp.where(take, p2, best_pose), jnp.where(take, f2, best_fit)
    return best_pose, best_fit


def _near(a, b, th):
    """Whether pose ``a`` is within ``max_shift`` and ``max_turn`` of pose ``b``."""
    return (jnp.hypot(*(a[:2] - b[:2])) <= th["max_shift"]) & (
        jnp.abs(se2.angle_diff(a[2], b[2])) <= th["max_turn"]
    )


def _step(th, carry, inp):
    prev, prev_odo, prev_inc, mpts, mnrm, mmask, slot = carry
    scan, smask, odo, valid, reset = inp
    pred = se2.compose(prev, se2.between(prev_odo, odo))
    K, P = mmask.shape
    flat = (mpts.reshape(K * P, 2), mnrm.reshape(K * P, 2), mmask.reshape(K * P))
    pose, inl, fit = _icp(pred, scan, smask, *flat, th)
    mapped = jnp.sum(mmask) >= th["min_inliers"]
    ok = (inl >= th["min_inliers"]) & mapped & _near(pose, pred, th) & jnp.all(jnp.isfinite(pose))
    pose = jnp.where(ok, pose, pred)
    # The jump test (step 5 of the module's doc), run only where the input's increment leaves
    # the scan fitting the local map poorly (``sparse_cond``: a real branch, also when the
    # odometry of many recordings is refined at once).
    poor = valid & ~reset & mapped & (fit > th["jump_fit"])
    alt = sparse_cond(poor, _alternatives, (prev, prev_inc, pred, scan, smask, flat, th))
    pose2, fit2 = jnp.where(poor, alt[0], pred), jnp.where(poor, alt[1], jnp.inf)
    better = (fit2 <= th["jump_fit"]) & (fit2 * th["jump_ratio"] <= fit)
    jump = poor & ~_near(pose2, pose, th) & better
    start = reset | jump
    pose = jnp.where(start, odo, pose)
    mmask = jnp.where(start, False, mmask)
    new_pts = mpts.at[slot].set(se2.apply(pose, scan))
    new_nrm = mnrm.at[slot].set(se2.rotate(pose[2], _normals(scan, smask, th["normal_radius"])))
    new_mask = mmask.at[slot].set(smask)
    inc = jnp.where(start, jnp.zeros_like(prev_inc), se2.between(prev, pose))
    out = (
        jnp.where(valid, pose, prev),
        jnp.where(valid, odo, prev_odo),
        jnp.where(valid, inc, prev_inc),
        jnp.where(valid, new_pts, mpts),
        jnp.where(valid, new_nrm, mnrm),
        jnp.where(valid, new_mask, mmask),
        jnp.where(valid, (slot + 1) % K, slot),
    )
    return out, (pose, ok, jump)


@jax.jit
def _chunk(th, carry, scans, smask, odo, valid, reset):
    """``lax.scan`` of ``_step`` over one chunk of keyframes of every recording at once
    (leaves ``(R, chunk, ...)``; the carry ``(R, ...)``)."""
    return jax.vmap(lambda c, *x: jax.lax.scan(partial(_step, th), c, x))(
        carry, scans, smask, odo, valid, reset
    )


def _thresholds(p: ScanMatchParams) -> dict:
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


class Odometer:
    """Refines a growing sequence of keyframes chunk by chunk (the kernel's state is kept).

    ``extend`` takes keyframes in order; the result for the first ``m`` keyframes never
    changes when more arrive, so the live path and the batch path agree. ``poses`` holds the
    refined poses so far; ``trusted`` whether each keyframe's match passed the inlier and
    correction checks (such a match may still keep the prediction under ``min_gain``);
    ``starts`` whether each keyframe starts an odometry segment (``segments``).

    Args:
        params: ``ScanMatchParams``.
    """

    def __init__(self, params: ScanMatchParams | None = None):
        self.params = params or ScanMatchParams()
        self._th = _thresholds(self.params)
        p = self.params
        self._carry = (
            np.zeros(3, np.float32),
            np.zeros(3, np.float32),
            np.zeros(3, np.float32),
            np.zeros((p.map_scans, p.points, 2), np.float32),
            np.zeros((p.map_scans, p.points, 2), np.float32),
            np.zeros((p.map_scans, p.points), bool),
            np.int32(0),
        )
        self.poses = np.zeros((0, 3), np.float64)
        self.trusted = np.zeros(0, bool)
        self.starts = np.zeros(0, bool)
        self._last_seg = None  # segment id of the last keyframe run
        self._origin = None  # the kernel works in float32 around the first keyframe's position

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def segments(self) -> np.ndarray:
        """``(M,)`` odometry segment of every keyframe so far: 0, plus one after every jump
        (the input's, as given to ``extend``, and those the jump test found)."""
        return np.maximum(np.cumsum(self.starts) - 1, 0).astype(np.int64)

    def extend(self, scans, odometry, segments) -> np.ndarray:
        """Adds keyframes; returns the refined poses ``(M, 3)`` of all keyframes so far.

        Args:
            scans: the new keyframes' scans, ``(n_i, 2)`` each, sensor frame.
            odometry: ``(m, 3)`` their input odometry poses.
            segments: ``(m,)`` their odometry segment ids (``windows.odometry_segments`` of
                the whole keyframe sequence): a change of id starts over.
        """
        return extend_many([self], [scans], [odometry], [segments])[0]

    def _given(self, odometry, segments):
        """Where the input's segment id changes (the first keyframe ever starts one)."""
        first = [self._last_seg != segments[0]] if len(segments) else []
        given = np.concatenate([first, segments[1:] != segments[:-1]]).astype(bool)
        if len(segments):
            self._last_seg = segments[-1]
        if self._origin is None and len(odometry):
            self._origin = np.array([*odometry[0, :2], 0.0])
        return given

    def _append(self, poses, trusted, starts):
        self.poses = np.concatenate([self.poses, poses])
        self.trusted = np.concatenate([self.trusted, trusted])
        self.starts = np.concatenate([self.starts, starts])
        return self.poses


def extend_many(odometers, scans, odometry, segments) -> list[np.ndarray]:
    """``Odometer.extend`` of several odometers (one per recording) in one batched kernel.

    The recordings' keyframes are fed chunk by chunk (``chunk`` keyframes of every
    recording per call, shorter ones padded), so one compilation serves any length; each
    recording's poses are exactly what its own ``extend`` would give.

    Returns:
        The refined poses ``(M_i, 3)`` of all keyframes so far, per odometer.
    """
    p = odometers[0].params
    odometry = [np.asarray(o, np.float64).reshape(-1, 3) for o in odometry]
    segments = [np.asarray(s).reshape(-1) for s in segments]
    given = [od._given(o, s) for od, o, s in zip(odometers, odometry, segments, strict=True)]
    if not p.enabled:
        return [od._append(o, np.zeros(len(o), bool), g)
                for od, o, g in zip(odometers, odometry, given, strict=True)]  # fmt: skip
    n = len(odometers)
    longest = max((len(o) for o in odometry), default=0)
    carry = jax.tree.map(lambda *xs: np.stack(xs), *[od._carry for od in odometers])
    out = [([], [], []) for _ in range(n)]
    for i0 in range(0, longest, p.chunk):
        S = np.zeros((n, p.chunk, p.points, 2), np.float32)
        M = np.zeros((n, p.chunk, p.points), bool)
        O = np.zeros((n, p.chunk, 3), np.float32)
        valid = np.zeros((n, p.chunk), bool)
        reset = np.zeros((n, p.chunk), bool)
        for r, od in enumerate(odometers):
            sl = slice(i0, min(i0 + p.chunk, len(odometry[r])))
            m = max(sl.stop - sl.start, 0)
            for j, sc in enumerate(scans[r][sl]):
                S[r, j], M[r, j] = thin_scan(sc, p)
            if m:
                O[r, :m] = odometry[r][sl] - od._origin
            valid[r, :m] = True
            reset[r, :m] = given[r][sl]
        carry, (pose, trusted, jump) = _chunk(odometers[0]._th, carry, S, M, O, valid, reset)
        pose, trusted, jump = (np.asarray(a) for a in (pose, trusted, jump))
        for r, od in enumerate(odometers):
            sl = slice(i0, min(i0 + p.chunk, len(odometry[r])))
            m = max(sl.stop - sl.start, 0)
            if m:
                out[r][0].append(pose[r, :m].astype(np.float64) + od._origin)
                out[r][1].append(trusted[r, :m] & ~given[r][sl])
                out[r][2].append(given[r][sl] | jump[r, :m])
    for r, od in enumerate(odometers):
        od._carry = jax.tree.map(lambda a, r=r: np.asarray(a)[r], carry)
        if out[r][0]:
            od._append(*(np.concatenate(x) for x in out[r]))
    return [od.poses for od in odometers]


def scan_match(scans, odometry, segments, params: ScanMatchParams | None = None) -> np.ndarray:
    """Refined poses ``(M, 3)`` of keyframes (``Odometer`` run once over all of them)."""
    return Odometer(params).extend(scans, odometry, segments)
