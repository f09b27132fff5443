"""TUM trajectories: ``t x y z qx qy qz qw`` per line, reduced to SE(2) poses.

The yaw is the rotation about z of the quaternion; roll, pitch and z are dropped (the sensor
is taken to move in the plane). Lines starting with ``#`` and blank lines are skipped.
Timestamps strictly increase (a repeated or earlier stamp is an error naming its line).

Quaternions (``unit_quaternions``, also for bag odometry): a norm off 1 by more than
``QUAT_NORM_TOL`` (1e-3; rounding to 6 digits stays far below it) is normalised with one
``DataWarning`` per file naming the first such line and its norm; a norm under
``QUAT_MIN_NORM`` (1e-6: below the digits a fixed-point writer keeps, no direction is left)
or a non-finite one is a ``DataError``. The yaw is read scale-free (``yaw_from_quat``), so a
quaternion scaled by 2 no longer reads 84 deg as 123 deg.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from mfcl_jax.io.atomic import atomic_write_text
from mfcl_jax.io.errors import DataError, DataWarning

__all__ = [
    "QUAT_NORM_TOL",
    "QUAT_MIN_NORM",
    "read_tum",
    "parse_tum",
    "write_tum",
    "format_time",
    "yaw_from_quat",
    "quat_from_yaw",
    "unit_quaternions",
]

QUAT_NORM_TOL = 1e-3
QUAT_MIN_NORM = 1e-6


def yaw_from_quat(q) -> np.ndarray:
    """Yaw (rad) of quaternions ``(*, 4)`` in ``(qx, qy, qz, qw)`` order.

    Both atan2 arguments scale with the squared norm, so a non-unit quaternion gives the yaw
    of its normalised rotation (``1 - 2 (y^2 + z^2)`` would not).
    """
    q = np.asarray(q, float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def _refuse_degenerate(q: np.ndarray, label: str) -> None:
    norm = float(np.linalg.norm(q))
    if not np.all(np.isfinite(q)) or norm < QUAT_MIN_NORM:
        raise DataError(
            f"{label}: degenerate quaternion (qx, qy, qz, qw) = {tuple(q.tolist())} with norm "
            f"{norm:.3g}; a rotation needs a unit quaternion"
        )


def unit_quaternions(q, labels) -> np.ndarray:
    """Unit quaternions ``(N, 4)`` from written ones (module rules).

    Args:
        q: ``(N, 4)`` quaternions ``(qx, qy, qz, qw)``.
        labels: ``N`` names for messages, e.g. ``"odometry.tum:12"``.

    Raises:
        DataError: a non-finite quaternion or one with norm under ``QUAT_MIN_NORM``.

    Warns:
        DataWarning: norms off 1 by more than ``QUAT_NORM_TOL`` (once: the first such
            quaternion, the count, the largest deviation).
    """
    q = np.asarray(q, np.float64).reshape(-1, 4)
    norm = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(~np.isfinite(norm) | (norm < QUAT_MIN_NORM))
    if len(bad):
        _refuse_degenerate(q[bad[0]], labels[bad[0]])
    off = np.flatnonzero(np.abs(norm - 1.0) > QUAT_NORM_TOL)
    if len(off):
        i, j = off[0], off[np.argmax(np.abs(norm[off] - 1.0))]
        warnings.warn(
            f"{labels[i]}: quaternion norm {norm[i]:.6g} differs from 1 by more than "
            f"{QUAT_NORM_TOL:g}; {len(off)} of {len(q)} quaternions are off like this (the "
            f"largest: norm {norm[j]:.6g} at {labels[j]}) and were normalised before reading "
            "the yaw",
            DataWarning,
            stacklevel=3,
        )
    return q / norm[:, None]


def quat_from_yaw(yaw) -> np.ndarray:
    """Quaternions ``(*, 4)`` (qx, qy, qz, qw) of rotations about z."""
    yaw = np.asarray(yaw, float)
    z = np.zeros_like(yaw)
    return np.stack([z, z, np.sin(yaw / 2), np.cos(yaw / 2)], -1)


def read_tum(path, with_strings: bool = False):
    """Reads a TUM trajectory.

    Args:
        path: the file.
        with_strings: also return each line's time exactly as written.

    Returns:
        ``(times (N,), poses (N, 3))`` with poses ``(x, y, yaw)``, plus the time strings
        ``list[str]`` when ``with_strings``.

    Raises:
        DataError: missing file, a line without 8 columns, a non-number or non-finite value,
            timestamps that do not strictly increase, a degenerate quaternion (each names
            the file and line).

    Warns:
        DataWarning: non-unit quaternions, normalised (``unit_quaternions``).
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    times, poses, strs = parse_tum(lines, path)
    return (times, poses, strs) if with_strings else (times, poses)


def parse_tum(lines, where, first_line: int = 1, after: float = -math.inf):
    """Parses TUM lines (``read_tum``'s rules), e.g. the lines appended to a growing file.

    Args:
        lines: the text lines.
        where: the file, for messages.
        first_line: number of ``lines[0]`` in the file (messages name file lines).
        after: the time of the line before ``lines[0]`` (times must keep increasing).

    Returns:
        ``(times (N,), poses (N, 3), time strings)``.
    """
    strs, rows, nos = [], [], []
    prev, prev_no = after, None
    for no, line in enumerate(lines, first_line):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        cols = s.split()
        if len(cols) != 8:
            raise DataError(
                f"{where}:{no}: expected 8 columns 't x y z qx qy qz qw', got {len(cols)}"
            )
        try:
            vals = [float(c) for c in cols]
        except ValueError:
            raise DataError(f"{where}:{no}: not a number in {s!r}") from None
        if not all(math.isfinite(v) for v in vals):
            raise DataError(f"{where}:{no}: non-finite value in {s!r}")
        if vals[0] <= prev:
            at = f" at line {prev_no}" if prev_no else ""
            why = "repeats it" if vals[0] == prev else "goes back in time"
            raise DataError(
                f"{where}:{no}: timestamp {cols[0]} does not increase (previous {prev!r}{at}: "
                f"{why}); the lines must be in strictly increasing time order"
            )
        _refuse_degenerate(np.asarray(vals[4:8]), f"{where}:{no}")
        prev, prev_no = vals[0], no
        strs.append(cols[0])
        rows.append(vals)
        nos.append(no)
    arr = np.asarray(rows, float).reshape(-1, 8)
    q = unit_quaternions(arr[:, 4:8], [f"{where}:{no}" for no in nos])
    poses = np.stack([arr[:, 1], arr[:, 2], yaw_from_quat(q)], -1)
    return arr[:, 0], poses, strs


def format_time(t: float) -> str:
    """The canonical time string: enough digits to round-trip, no exponent."""
    return f"{t:.9f}".rstrip("0").rstrip(".") if math.isfinite(t) else str(t)


def write_tum(path, times, poses, time_strings=None) -> Path:
    """Writes SE(2) poses ``(N, 3)`` at ``times (N,)`` as a TUM file (atomically).

    Raises:
        DataError: mismatched lengths, non-finite values or non-increasing times.
    """
    path = Path(path)
    times = np.asarray(times, float).reshape(-1)
    poses = np.asarray(poses, float).reshape(-1, 3)
    if len(times) != len(poses):
        raise DataError(f"{path}: {len(times)} times but {len(poses)} poses")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(poses))):
        raise DataError(f"{path}: non-finite time or pose")
    if np.any(np.diff(times) <= 0):
        i = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise DataError(f"{path}: times must increase (entry {i}: {times[i]!r})")
    strs = time_strings or [format_time(t) for t in times]
    q = quat_from_yaw(poses[:, 2])
    lines = ["# t x y z qx qy qz qw"]
    for s, p, qq in zip(strs, poses, q, strict=True):
        # x, y round-trip exactly (repr): georeferenced poses (~5e6 m) keep their millimetres.
        x, y = repr(float(p[0])), repr(float(p[1]))
        lines.append(f"{s} {x} {y} 0 {qq[0]:.9g} {qq[1]:.9g} {qq[2]:.9g} {qq[3]:.9g}")
    return atomic_write_text(path, "\n".join(lines) + "\n")
