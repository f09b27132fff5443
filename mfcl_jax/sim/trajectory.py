"""Scan poses along a waypoint path, and drifting odometry for them.

Two frames: B (the floor plan) and L (the robot's LiDAR-inertial odometry frame). The robot
walks a smoothed polyline in B and keeps a scan (an LIO keyframe) every ``scan_spacing`` metres
of travel. Its odometry reports the same poses in L, related to B by a hidden anchor
``A = ^B T_L`` and corrupted by a random-walk drift.

Host code builds the paths (NumPy; tiny); the odometry integration is a pure JAX function.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2

__all__ = ["TrajectoryParams", "Path", "sample_path", "odometry"]


@dataclass(frozen=True)
class TrajectoryParams:
    """How the robot moves and how its odometry drifts.

    Attributes:
        scan_spacing: travel between kept scans (m). 0.25 m is a typical LIO keyframe spacing;
            a 6 m window then holds 25 scans.
        speed: walking speed (m/s), only for time stamps (0.5 m/s: a slow indoor robot).
        corner_smoothing: length (m) of the moving average applied to the densely resampled
            polyline; rounds corners (radius of the order of a quarter of it) so that heading
            changes continuously, as a wheeled robot's does.
        drift_xy: standard deviation of the translation error of each odometry increment, per
            axis, as a fraction of the increment length (0.005 = 0.5 %). Errors accumulate as
            a random walk.
        drift_yaw_deg_per_m: standard deviation of the yaw error per metre of increment (deg/m).
            With the defaults and 0.25 m steps, a 60 m run ends with about 0.4 deg of yaw drift
            and 0.1-0.3 m of position drift: a good LIO, so that failures are geometric.
    """

    scan_spacing: float = 0.25
    speed: float = 0.5
    corner_smoothing: float = 1.5
    drift_xy: float = 0.005
    drift_yaw_deg_per_m: float = 0.1

    def __post_init__(self):
        for name in ("scan_spacing", "speed"):
            v = getattr(self, name)
            if not v > 0:
                raise ValueError(f"TrajectoryParams.{name} must be > 0, got {name}={v!r}")
        for name in ("corner_smoothing", "drift_xy", "drift_yaw_deg_per_m"):
            v = getattr(self, name)
            if not v >= 0:
                raise ValueError(f"TrajectoryParams.{name} must be >= 0, got {name}={v!r}")


@dataclass(frozen=True)
class Path:
    """True scan poses of one trajectory.

    Attributes:
        poses: ``(T, 3)`` float64 true sensor poses ``^B T_t``.
        s: ``(T,)`` travelled distance along the path (m), starts at 0.
        t: ``(T,)`` time stamps (s).
    """

    poses: np.ndarray
    s: np.ndarray
    t: np.ndarray


def _arclength(xy: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])


def _resample(xy: np.ndarray, step: float) -> np.ndarray:
    s = _arclength(xy)
    n = int(np.floor(s[-1] / step + 1e-9)) + 1
    q = np.arange(n) * step
    return np.stack([np.interp(q, s, xy[:, 0]), np.interp(q, s, xy[:, 1])], axis=1)


def sample_path(waypoints, params: TrajectoryParams = TrajectoryParams()) -> Path:
    """Samples scan poses every ``params.scan_spacing`` metres along a waypoint polyline.

    Args:
        waypoints: ``(P, 2)`` polyline in B (P >= 2, consecutive points distinct).
        params: spacing, speed and corner smoothing.

    Returns:
        A ``Path`` whose headings follow the smoothed path tangent.
    """
    wp = np.asarray(waypoints, dtype=np.float64)
    if wp.ndim != 2 or wp.shape[1] != 2 or len(wp) < 2 or not np.all(np.isfinite(wp)):
        raise ValueError(f"waypoints must be finite (P>=2, 2), got shape {wp.shape}")
    if np.any(np.linalg.norm(np.diff(wp, axis=0), axis=1) < 1e-9):
        raise ValueError("waypoints contain two identical consecutive points")
    fine = 0.02
    dense = _resample(wp, fine)
    half = int(round(params.corner_smoothing / (2 * fine)))
    if half > 0 and len(dense) > 2 * half + 1:
        # Moving average over an odd reflection about each end point: the path still starts
        # and ends at the first and last waypoint and straight stretches stay exact.
        ker = np.ones(2 * half + 1) / (2 * half + 1)
        head = 2 * dense[0] - dense[half:0:-1]
        tail = 2 * dense[-1] - dense[-2 : -half - 2 : -1]
        padded = np.concatenate([head, dense, tail])
        dense = np.stack([np.convolve(padded[:, i], ker, mode="valid") for i in range(2)], 1)
    xy = _resample(dense, params.scan_spacing)
    d = np.gradient(xy, axis=0) if len(xy) > 1 else np.array([[1.0, 0.0]])
    theta = np.arctan2(d[:, 1], d[:, 0])
    s = np.arange(len(xy)) * params.scan_spacing
    poses = np.concatenate([xy, theta[:, None]], axis=1)
    return Path(poses=poses, s=s, t=s / params.speed)


def odometry(true_poses, anchor, noise, drift_xy, drift_yaw):
    """Odometry poses in L from true poses in B (pure; jit/vmap friendly).

    Each increment ``d_t = Y_{t-1}^-1 Y_t`` is perturbed by ``(e_x, e_y, e_yaw)`` with
    ``e_xy ~ N(0, (drift_xy |d_t|)^2)`` and ``e_yaw ~ N(0, (drift_yaw |d_t|)^2)`` and the
    perturbed increments are chained from ``X_0 = A^-1 Y_0``.

    Args:
        true_poses: ``(T, 3)`` true poses ``^B T_t``.
        anchor: ``(3,)`` hidden ``A = ^B T_L``.
        noise: ``(T, 3)`` standard normal draws (row 0 unused).
        drift_xy: translation drift per metre of increment (fraction).
        drift_yaw: yaw drift per metre of increment (rad/m).

    Returns:
        ``(T, 3)`` odometry poses ``^L T_t``.
    """
    y = jnp.asarray(true_poses)
    inc = se2.between(y[:-1], y[1:])
    length = jnp.linalg.norm(inc[:, :2], axis=-1)
    scale = jnp.stack([drift_xy * length, drift_xy * length, drift_yaw * length], axis=-1)
    inc = se2.compose(inc, noise[1:] * scale)
    # Chaining increments: yaw is a cumulative sum; each translation is rotated by the heading
    # reached before it (no sequential scan needed).
    x0 = se2.compose(se2.inverse(anchor), y[0])
    yaw = x0[2] + jnp.concatenate([jnp.zeros(1, y.dtype), jnp.cumsum(inc[:, 2])])
    steps = se2.rotate(yaw[:-1], inc[:, :2])
    xy = x0[:2] + jnp.concatenate([jnp.zeros((1, 2), y.dtype), jnp.cumsum(steps, axis=0)])
    return jnp.concatenate([xy, se2.wrap(yaw)[:, None]], axis=-1)
