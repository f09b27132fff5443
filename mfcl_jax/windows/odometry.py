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

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.sparse_cond import sparse_cond
from mfcl_jax.windows.icp import ScanMatchParams, icp, normals, thin_scan, thresholds

__all__ = ["ScanMatchParams", "Odometer", "extend_many", "scan_match", "thin_scan", "LIVE_CHUNK"]

# Keyframes per kernel call on a live stream (``Cutter(live=True)``): a robot adds one
# keyframe at a time, and a call costs its whole chunk (the scan runs masked steps too), so a
# chunk of 32 made every new keyframe cost about 60 ms on 2 cores; 4 costs about 8 ms. The
# masked steps leave the carry as it was, so the poses do not depend on the chunk.
LIVE_CHUNK = 4


def _alternatives(ops):
    """The jump test's two matches that ignore the input (module doc, step 5)."""
    prev, prev_inc, pred, scan, smask, flat, th = ops
    best_pose, best_fit = pred, jnp.asarray(jnp.inf, pred.dtype)
    for guess in (se2.compose(prev, prev_inc), prev):  # kept moving as it was; stood still
        p2, i2, f2 = icp(guess, scan, smask, *flat, th)
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
    pose, inl, fit = icp(pred, scan, smask, *flat, th)
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
    new_nrm = mnrm.at[slot].set(se2.rotate(pose[2], normals(scan, smask, th["normal_radius"])))
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
        self._th = thresholds(self.params)
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

    def extend(self, scans, odometry, segments, chunk: int | None = None) -> np.ndarray:
        """Adds keyframes; returns the refined poses ``(M, 3)`` of all keyframes so far.

        Args:
            scans: the new keyframes' scans, ``(n_i, 2)`` each, sensor frame.
            odometry: ``(m, 3)`` their input odometry poses.
            segments: ``(m,)`` their odometry segment ids (``windows.odometry_segments`` of
                the whole keyframe sequence): a change of id starts over.
            chunk: keyframes per kernel call (default ``params.chunk``; ``LIVE_CHUNK``).
        """
        return extend_many([self], [scans], [odometry], [segments], chunk=chunk)[0]

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


def extend_many(odometers, scans, odometry, segments, rows: int = 1,
                chunk: int | None = None) -> list[np.ndarray]:  # fmt: skip
    """``Odometer.extend`` of several odometers (one per recording) in one batched kernel.

    The recordings' keyframes are fed chunk by chunk (``chunk`` keyframes of every
    recording per call, shorter ones padded), so one compilation serves any length; each
    recording's poses are exactly what its own ``extend`` would give. ``rows``: the least
    recordings per call (idle rows padded), so that batches of fewer share the compilation.
    ``chunk``: keyframes per call (default ``params.chunk``; one compilation per value).

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
    n = max(len(odometers), rows)
    longest = max((len(o) for o in odometry), default=0)
    idle = [odometers[0]._carry] * (n - len(odometers))
    carry = jax.tree.map(lambda *xs: np.stack(xs), *[od._carry for od in odometers], *idle)
    out = [([], [], []) for _ in odometers]
    size = p.chunk if chunk is None else int(chunk)
    for i0 in range(0, longest, size):
        S = np.zeros((n, size, p.points, 2), np.float32)
        M = np.zeros((n, size, p.points), bool)
        O = np.zeros((n, size, 3), np.float32)
        valid = np.zeros((n, size), bool)
        reset = np.zeros((n, size), bool)
        for r, od in enumerate(odometers):
            sl = slice(i0, min(i0 + size, len(odometry[r])))
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
            sl = slice(i0, min(i0 + size, len(odometry[r])))
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
