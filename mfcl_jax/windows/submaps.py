"""Submap windows: the one place where a scan sequence is cut into padded submaps.

Every consumer (the study, the benchmark, ``mfcl localize``) goes through here:

1. keyframes (``keyframes.keyframes``): a scan is kept once the odometry moved
   ``keyframe_spacing`` or turned ``keyframe_turn_deg`` since the last kept one, as an LIO
   keeps keyframes. The threshold (0.20 m) sits below the simulator's 0.25 m scan spacing, so
   a simulated sequence keeps every scan despite its drift;
2. sliding windows over odometric travelled distance (``keyframes.window_bounds``): the robot
   decides them from its own odometry, so drift shifts the windows as on a robot;
3. LiDAR odometry (``odometry``): the keyframes' poses refined by ICP against a local map of
   the previous keyframes (``scan_match.enabled``), so that wheel odometry's drift does not bend
   the submaps; the windows' bounds stay those of the input odometry's travel;
4. the submap (``build_submap``) in the frame ``S_i`` of the window's last scan
   (``X_i = ^L T_{S_i}``, the refined pose): every scan moved by its refined pose (what drift
   is left distorts it as it distorts a real accumulated cloud), cropped, voxel-thinned, each
   point keeping its ray origin so the ray between them is known free space. A submap over
   the point capacity is re-thinned with a coarser voxel (x1.5 until it fits, at most
   ``max_rethin`` times); nothing is truncated;
5. ``pack`` (``padding``): windows of many runs padded on the host into one ``SubmapBatch``
   (points in a power-of-two capacity bucket) and one ``RunBatch``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.windows.keyframes import keyframes, odometry_segments, segment_bounds
from mfcl_jax.windows.odometry import Odometer, ScanMatchParams

__all__ = [
    "WindowParams",
    "Windows",
    "build_submap",
    "cut",
    "rethinned",
    "window",
]


@dataclass(frozen=True)
class WindowParams:
    """How a sequence is cut into submaps.

    Attributes:
        d_s: window length (m of odometric travel).
        step: window start advance (m); 2 m as in the paper.
        voxel: voxel edge (m), one point kept per voxel. 0.10 m matches the floor-plan raster,
            so finer clouds cost more and add nothing to a distance-field score.
        crop_radius: points farther than this (m) from the ``S_i`` origin are dropped
            (``None`` keeps all). 10 m: a 5-7 m window describes the local structure around the
            swept path; the long grazing views through doors are the noisiest returns, and
            without the crop a submap of a 14 m room also holds its neighbours' far walls, so
            the one-room aliases the paper studies nearly vanish.
        keyframe_spacing, keyframe_turn_deg: keyframe thresholds (m, deg).
        capacity: the largest point capacity of a submap; a window over it is re-thinned.
        min_capacity: the smallest capacity bucket.
        max_rethin: re-thinning rounds (voxel x1.5 each) before an over-full window is an error.
        scan_match: the LiDAR odometry (``scanmatch.ScanMatchParams``).
    """

    d_s: float = 6.0
    step: float = 2.0
    voxel: float = 0.10
    crop_radius: float | None = 10.0
    keyframe_spacing: float = 0.20
    keyframe_turn_deg: float = 20.0
    capacity: int = 4096
    min_capacity: int = 256
    max_rethin: int = 6
    scan_match: ScanMatchParams = field(default_factory=ScanMatchParams)

    def __post_init__(self):
        for name in ("d_s", "step", "voxel", "keyframe_spacing", "keyframe_turn_deg"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and v > 0):
                raise ValueError(f"WindowParams: {name} must be > 0, got {name}={v!r}")
        if self.crop_radius is not None and not self.crop_radius > 0:
            raise ValueError(f"WindowParams: crop_radius must be > 0, got {self.crop_radius!r}")
        if self.capacity < 64:
            raise ValueError(f"WindowParams: capacity must be >= 64, got {self.capacity!r}")


def _between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b`` for one pose ``a (3,)`` and poses ``b (n, 3)`` (float64, host)."""
    c, s = np.cos(a[2]), np.sin(a[2])
    d = b[:, :2] - a[:2]
    x = c * d[:, 0] + s * d[:, 1]
    y = -s * d[:, 0] + c * d[:, 1]
    return np.stack([x, y, b[:, 2] - a[2]], axis=1)


def build_submap(scans, X, voxel: float = 0.10, crop_radius: float | None = 10.0):
    """One submap from ``scans`` in the frame of the LAST scan.

    Args:
        scans: ``n_s`` arrays ``(n_i, 2)`` (or one ``(n_s, B, 2)`` array, NaN where invalid),
            points in each scan's sensor frame, oldest first.
        X: ``(n_s, 3)`` odometry poses of the scans.
        voxel: voxel edge (m).
        crop_radius: crop radius (m) around the last scan, or ``None``.

    Returns:
        ``(points (n, 2), origins (n, 2))`` float64 in ``S_i``, one point per voxel: the one
        from the latest scan, the least distorted by drift relative to ``S_i``.
    """
    X = np.asarray(X, dtype=np.float64)
    rel = _between(X[-1], X[::-1])  # latest scan first
    parts, orgs = [], []
    for r, s in zip(rel, scans[::-1], strict=True):
        s = np.asarray(s, np.float64).reshape(-1, 2)
        c, si = np.cos(r[2]), np.sin(r[2])
        parts.append(
            np.stack([c * s[:, 0] - si * s[:, 1] + r[0], si * s[:, 0] + c * s[:, 1] + r[1]], -1)
        )
        orgs.append(np.broadcast_to(r[:2], (len(s), 2)))
    p = np.concatenate(parts) if parts else np.zeros((0, 2))
    o = np.concatenate(orgs) if orgs else np.zeros((0, 2))
    keep = np.all(np.isfinite(p), axis=1)
    if crop_radius is not None:
        keep &= np.einsum("ij,ij->i", p, p) <= crop_radius**2
    p, o = p[keep], o[keep]
    if len(p) == 0:
        return p, o
    cell = np.floor(p / voxel).astype(np.int64)
    # One int64 per voxel (cells within +-2^20 voxels of S_i: 100 km at 0.1 m).
    code = (cell[:, 0] + (1 << 20)) * (1 << 21) + (cell[:, 1] + (1 << 20))
    _, first = np.unique(code, return_index=True)
    first.sort()
    return p[first], o[first]


@dataclass(frozen=True, eq=False)
class Windows:
    """The windows of one sequence at one ``d_s`` (host arrays).

    Attributes:
        keyframes: ``(M,)`` indices of the keyframes into the sequence.
        bounds: ``(K, 2)`` inclusive keyframe ranges of the windows.
        points, origins: ``K`` arrays ``(n_k, 2)`` in ``S_k``.
        voxel: ``(K,)`` voxel edge used per window (larger where re-thinned).
        X: ``(K, 3)`` pose of each window's last scan in the layer's odometry (refined by the
            LiDAR odometry where enabled): the ``X_i`` of the anchors ``Y X^-1``.
        t: ``(K,)`` time of each window's last scan.
        params: the ``WindowParams`` used.
        odometry: ``(M, 3)`` the layer's odometry at every keyframe.
        X_input: ``(K, 3)`` the input odometry at each window's last scan (an anchor of the
            layer's frame is reported in the input's by ``robot.records.record``).
        segments: ``(M,)`` odometry segment of every keyframe: 0, plus one after every jump,
            whether the input odometry's step shows it (``odometry_segments``) or the LiDAR
            odometry's jump test finds it (``scanmatch``). No window straddles a jump.
        last_points: ``K`` arrays ``(n_k, 2)``: each window's last scan alone (its valid
            points within the crop radius), in ``S_k``, its own frame: the only points that
            no odometry increment has moved (``arrays.end_sample``).
    """

    keyframes: np.ndarray
    bounds: np.ndarray
    points: list
    origins: list
    voxel: np.ndarray
    X: np.ndarray
    t: np.ndarray
    params: WindowParams
    odometry: np.ndarray
    X_input: np.ndarray
    segments: np.ndarray
    last_points: list

    def __len__(self) -> int:
        return len(self.bounds)

    def last_scan(self) -> np.ndarray:
        """``(K,)`` index into the sequence of each window's last scan."""
        return self.keyframes[self.bounds[:, 1]] if len(self.bounds) else np.zeros(0, int)


def _thinned(seq, idx, poses, p: WindowParams):
    scans = [seq.scans[i] for i in idx]
    voxel = p.voxel
    for _ in range(p.max_rethin + 1):
        pts, org = build_submap(scans, poses, voxel, p.crop_radius)
        if len(pts) <= p.capacity:
            return pts, org, voxel
        voxel *= 1.5
    raise DataError(
        f"{seq.source}: window of scans {idx[0]}..{idx[-1]} keeps {len(pts)} points at "
        f"voxel {voxel / 1.5:.2f} m, over the capacity {p.capacity}"
    )


def keyframe_odometry(seq, kf, p: WindowParams, odometer: Odometer | None = None):
    """The layer's odometry at the keyframes ``kf``: ``(poses (M, 3), segments (M,))``, the
    input's poses refined by the LiDAR odometry where ``p.scan_match.enabled``, and the
    odometry segments (``Windows.segments``).

    ``odometer``: an ``Odometer`` already fed the first keyframes of this sequence (the live
    path, which sees ever longer prefixes); it is extended with the rest.
    """
    raw = np.asarray(seq.odometry, np.float64)[kf]
    odo = odometer if odometer is not None else Odometer(p.scan_match)
    n = len(odo)
    if n > len(kf):
        raise ValueError(f"{seq.source}: odometer fed {n} keyframes, the sequence has {len(kf)}")
    seg = odometry_segments(raw, np.asarray(seq.times)[kf])
    poses = odo.extend([seq.scans[i] for i in kf[n:]], raw[n:], seg[n:])
    return poses[: len(kf)], odo.segments[: len(kf)]


def cut(
    seq,
    params: WindowParams | None = None,
    upto: int | None = None,
    start: int = 0,
    odometer: Odometer | None = None,
) -> Windows:
    """Cuts a ``ScanSequence`` into windows (``upto``: only the first ``upto`` windows;
    ``start``: leave out the first ``start``, e.g. those a live run has already seen;
    ``odometer``: see ``keyframe_odometry``).

    Windows are causal: cutting a prefix of a sequence gives the first windows of the whole.
    """
    p = params or WindowParams()
    kf = keyframes(seq.odometry, p.keyframe_spacing, p.keyframe_turn_deg)
    odo, seg = keyframe_odometry(seq, kf, p, odometer)
    return _windows(seq, p, kf, odo, seg, start, upto)


def _windows(seq, p: WindowParams, kf, odo, seg, start: int = 0, upto: int | None = None):
    raw = np.asarray(seq.odometry, np.float64)[kf]
    bounds = segment_bounds(raw, seg, p.d_s, p.step)[start:upto]
    pts, orgs, vox = [], [], []
    for j0, j1 in bounds:
        a, o, v = _thinned(seq, kf[j0 : j1 + 1], odo[j0 : j1 + 1], p)
        pts.append(a)
        orgs.append(o)
        vox.append(v)
    last = bounds[:, 1] if len(bounds) else np.zeros(0, int)
    return Windows(
        kf,
        bounds,
        pts,
        orgs,
        np.asarray(vox, np.float64),
        odo[last].reshape(-1, 3),
        np.asarray(seq.times, np.float64)[kf[last]],
        p,
        odo,
        raw[last].reshape(-1, 3),
        seg,
        [_own(seq.scans[kf[j1]], p.crop_radius) for _, j1 in bounds],
    )


def _own(scan, crop_radius: float | None) -> np.ndarray:
    """A scan's valid points within ``crop_radius`` of its origin, in its own frame."""
    s = np.asarray(scan, np.float64).reshape(-1, 2)
    keep = np.all(np.isfinite(s), axis=1)
    if crop_radius is not None:
        keep &= np.einsum("ij,ij->i", s, s) <= crop_radius**2
    return s[keep].astype(np.float32)


def window(w: Windows, k: int) -> Windows:
    """Window ``k`` of ``w`` alone (same keyframes)."""
    sl = slice(k, k + 1)
    return Windows(
        w.keyframes, w.bounds[sl], w.points[sl], w.origins[sl], w.voxel[sl], w.X[sl], w.t[sl],
        w.params, w.odometry, w.X_input[sl], w.segments, w.last_points[sl],
    )  # fmt: skip


def rethinned(w: Windows) -> np.ndarray:
    """``(K,)`` bool: windows thinned with a coarser voxel than configured."""
    return w.voxel > w.params.voxel * (1 + 1e-9)
