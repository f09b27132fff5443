"""The covariance of a committed pose, from how the window's scans fit the plan there.

A Laplace approximation of the scan-to-plan fit: each submap point placed at the pose
``(x, y, yaw)`` has the residual ``d(p)``, its distance to the nearest wall (the plan's
distance field, ``floorplan.raster``); points within ``INLIER_M`` of a wall are the fit's
inliers. With the Jacobian ``J`` of the residuals in the pose (rotation about the pose's own
position) and the residuals' variance ``s2`` (their mean square, at least ``SIGMA_MIN_M``
squared: the plan's own tolerance), the information is ``J^T J / s2``, plus a prior of the
judging line (1 m, 5 deg: what a correct commit is allowed to be off by), and the covariance
its inverse. Points are not independent where a wall of the plan is off as built, so the
points within one ``CELL_M`` cell count as one observation (each weighted by one over their
number): a window that sees 40 m of wall counts about 40 observations, not its 900 points.
A corridor whose walls all run one way gives a large variance along it; a room corner a
small one in every direction.

The covariance is then carried from the sensor to the robot's base (``to_base``), the frame
``/initialpose`` names.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["pose_covariance", "to_base", "INLIER_M", "SIGMA_MIN_M", "CELL_M", "PRIOR"]

INLIER_M = 0.3
SIGMA_MIN_M = 0.05  # the plan's tolerance (as built) and the raster's cell
CELL_M = 1.0
PRIOR = (1.0, 1.0, math.radians(5.0))  # m, m, rad: the judging line


def _field(rasters, xy):
    """Bilinear distance ``(n,)`` and its gradient ``(n, 2)`` at ``xy`` (host NumPy)."""
    dist = np.asarray(rasters.dist, np.float64)
    h, w = dist.shape
    f = (xy - np.asarray(rasters.origin, np.float64)) / rasters.res - 0.5
    x0 = np.clip(np.floor(f[:, 0]).astype(int), 0, w - 2)
    y0 = np.clip(np.floor(f[:, 1]).astype(int), 0, h - 2)
    ax = np.clip(f[:, 0] - x0, 0.0, 1.0)
    ay = np.clip(f[:, 1] - y0, 0.0, 1.0)
    v00, v01 = dist[y0, x0], dist[y0, x0 + 1]
    v10, v11 = dist[y0 + 1, x0], dist[y0 + 1, x0 + 1]
    d = (1 - ay) * ((1 - ax) * v00 + ax * v01) + ay * ((1 - ax) * v10 + ax * v11)
    gx = ((1 - ay) * (v01 - v00) + ay * (v11 - v10)) / rasters.res
    gy = ((1 - ax) * (v10 - v00) + ax * (v11 - v01)) / rasters.res
    return d, np.stack([gx, gy], -1)


def pose_covariance(rasters, points, pose) -> np.ndarray:
    """``(3, 3)`` covariance of ``pose = (x, y, yaw)`` (the sensor in the plan's local frame)
    from the fit of ``points (n, 2)`` (sensor frame) to the plan's ``rasters``."""
    pose = np.asarray(pose, np.float64)
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    xy = pts @ np.array([[c, s], [-s, c]]) + pose[:2]
    info = np.diag(1.0 / np.square(PRIOR))
    if len(xy):
        d, g = _field(rasters, xy)
        inl = d < INLIER_M
        if inl.any():
            rel = xy[inl] - pose[:2]
            J = np.stack([g[inl, 0], g[inl, 1], -g[inl, 0] * rel[:, 1] + g[inl, 1] * rel[:, 0]], 1)
            s2 = max(float(np.mean(np.square(d[inl]))), SIGMA_MIN_M**2)
            _, cell, count = np.unique(np.floor(xy[inl] / CELL_M), axis=0, return_inverse=True,
                                       return_counts=True)  # fmt: skip
            w = 1.0 / count[cell.reshape(-1)]
            info = info + (J * w[:, None]).T @ J / s2
    cov = np.linalg.inv(info)
    return 0.5 * (cov + cov.T)


def to_base(cov, sensor_pose, base_pose) -> np.ndarray:
    """``cov`` of the sensor pose (rotation about the sensor) as the covariance of the base
    pose rigidly attached to it (rotation about the base)."""
    dx, dy = np.asarray(base_pose[:2], np.float64) - np.asarray(sensor_pose[:2], np.float64)
    A = np.array([[1.0, 0.0, -dy], [0.0, 1.0, dx], [0.0, 0.0, 1.0]])
    out = A @ np.asarray(cov, np.float64) @ A.T
    return 0.5 * (out + out.T)
