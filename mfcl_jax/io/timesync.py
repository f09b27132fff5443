"""Odometry at any rate: poses looked up at the scans' stamps by time.

Every input's odometry goes through ``odometry_at``: a dataset's ``odometry.tum`` (and
``poses_at`` for its ``groundtruth.tum``), a bag's ``/odom`` or ``/tf``, a CARMEN log's FLASER
odometry. The rules:

- Stamps are numbers (s), never strings: a scan ``scans/1000.5.pcd`` and an odometry line
  ``1000.500000`` are the same instant.
- The odometry's stamps strictly increase (each reader checks its lines and names the bad
  one; ``odometry_at`` checks again and names the entry).
- A scan stamp inside the odometry's span gets the odometry interpolated to it
  (``interpolate_se2``: position linear, heading along the shorter way round), so odometry
  may come at any rate (100 Hz wheel odometry, 10 Hz scans). A scan stamp equal to an odometry
  stamp gets that pose.
- ``TIME_TOL_S`` = 1 ms (the scorer's tolerance too, ``score.decisions.pose_at``): a scan
  stamp up to 1 ms before the first or after the last odometry stamp takes that end pose (a
  robot at 2 m/s moves 2 mm in 1 ms); the odometry is never extrapolated further.
- Scans further outside are left out with one ``DataWarning`` naming the file, how many were
  left out and the span; when every scan is outside it is a ``DataError``.

Pure NumPy in float64: stamps since the epoch (~1.7e9 s) keep about 0.2 us in float64.
"""

from __future__ import annotations

import warnings

import numpy as np

from mfcl_jax.io.errors import DataError, DataWarning
from mfcl_jax.se2 import wrap_host

__all__ = ["TIME_TOL_S", "interpolate_se2", "odometry_at", "poses_at"]

TIME_TOL_S = 1e-3


def interpolate_se2(times, poses, t) -> np.ndarray:
    """Poses at times ``t``, linear in position, the heading along the shorter way round.

    Args:
        times: ``(M,)`` strictly increasing stamps (s), ``M >= 1``.
        poses: ``(M, 3)`` poses ``(x, y, yaw)`` at ``times``.
        t: ``(K,)`` stamps; those outside ``[times[0], times[-1]]`` take the end pose.

    Returns:
        ``(K, 3)`` float64 poses, yaw wrapped to ``[-pi, pi]``.
    """
    times = np.asarray(times, np.float64).reshape(-1)
    poses = np.asarray(poses, np.float64).reshape(-1, 3)
    t = np.clip(np.asarray(t, np.float64).reshape(-1), times[0], times[-1])
    if len(times) == 1:
        return np.repeat(poses, len(t), 0)
    j = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    w = (t - times[j]) / (times[j + 1] - times[j])
    a, b = poses[j], poses[j + 1]
    # (1 - w) a + w b returns a and b exactly at w = 0 and 1: an odometry line at the scan's
    # stamp gives its own pose.
    xy = (1.0 - w)[:, None] * a[:, :2] + w[:, None] * b[:, :2]
    yaw = wrap_host(a[:, 2] + w * wrap_host(b[:, 2] - a[:, 2]))
    return np.concatenate([xy, yaw[:, None]], 1)


def _checked(times, poses, where: str, what: str) -> tuple[np.ndarray, np.ndarray]:
    times = np.asarray(times, np.float64).reshape(-1)
    poses = np.asarray(poses, np.float64).reshape(-1, 3)
    if len(times) == 0 or len(times) != len(poses):
        raise DataError(f"{where}: {len(times)} {what} stamps and {len(poses)} poses")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(poses))):
        i = int(np.flatnonzero(~np.isfinite(times) | ~np.all(np.isfinite(poses), 1))[0])
        raise DataError(f"{where}: non-finite {what} stamp or pose at entry {i}")
    bad = np.flatnonzero(np.diff(times) <= 0)
    if len(bad):
        i = int(bad[0]) + 1
        raise DataError(
            f"{where}: {what} stamps must strictly increase; entry {i} has "
            f"t={float(times[i])!r} after t={float(times[i - 1])!r}"
        )
    return times, poses


def _span(times) -> str:
    return f"[{times[0]:.6f}, {times[-1]:.6f}] s"


def _inside(times, t) -> np.ndarray:
    return (t >= times[0] - TIME_TOL_S) & (t <= times[-1] + TIME_TOL_S)


def odometry_at(
    times, poses, scan_times, where: str, what: str = "odometry"
) -> tuple[np.ndarray, np.ndarray]:
    """The odometry at each scan stamp; scans outside its span are left out (module rules).

    Args:
        times: ``(M,)`` odometry stamps (s), strictly increasing.
        poses: ``(M, 3)`` odometry poses.
        scan_times: ``(N,)`` scan stamps (s).
        where: the odometry's file (and topic), for messages.
        what: the odometry's name in messages.

    Returns:
        ``(inside (N,) bool, poses (K, 3))``: which scans lie within the span (``K`` of them)
        and the odometry at their stamps.

    Raises:
        DataError: no odometry, stamps that do not strictly increase, non-finite values, or
            no scan within the span (the message gives both spans).

    Warns:
        DataWarning: some scans lie outside the span (their count, the first, the span).
    """
    times, poses = _checked(times, poses, where, what)
    st = np.asarray(scan_times, np.float64).reshape(-1)
    inside = _inside(times, st)
    out = np.flatnonzero(~inside)
    if len(st) and len(out) == len(st):
        raise DataError(
            f"{where}: no scan lies within the {what}'s time span {_span(times)} (tolerance "
            f"{TIME_TOL_S * 1e3:g} ms); the {len(st)} scans span "
            f"[{st.min():.6f}, {st.max():.6f}] s"
        )
    if len(out):
        warnings.warn(
            f"{where}: {len(out)} of {len(st)} scans lie outside the {what}'s time span "
            f"{_span(times)} (tolerance {TIME_TOL_S * 1e3:g} ms) and were left out; the first "
            f"at t={st[out[0]]:.6f} s",
            DataWarning,
            stacklevel=3,
        )
    return inside, interpolate_se2(times, poses, st[inside])


def poses_at(times, poses, t, where: str, what: str = "ground truth") -> np.ndarray:
    """Poses ``(K, 3)`` at every stamp of ``t (K,)`` (for ground truth: none may be missing).

    Raises:
        DataError: as ``odometry_at``, or a stamp outside the span (the first is named).
    """
    times, poses = _checked(times, poses, where, what)
    t = np.asarray(t, np.float64).reshape(-1)
    out = np.flatnonzero(~_inside(times, t))
    if len(out):
        raise DataError(
            f"{where}: {len(out)} of {len(t)} scans lie outside the {what}'s time span "
            f"{_span(times)} (tolerance {TIME_TOL_S * 1e3:g} ms), the first at "
            f"t={t[out[0]]:.6f} s; the {what} must cover every scan"
        )
    return interpolate_se2(times, poses, t)
