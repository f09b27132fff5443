"""TUM trajectories: ``t x y z qx qy qz qw`` per line, reduced to SE(2) poses.

The yaw is the rotation about z of the quaternion; roll, pitch and z are dropped (the sensor
is taken to move in the plane). Lines starting with ``#`` and blank lines are skipped.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mfcl_jax.io.errors import DataError, atomic_write_text

__all__ = ["read_tum", "parse_tum", "write_tum", "format_time", "yaw_from_quat", "quat_from_yaw"]


def yaw_from_quat(q) -> np.ndarray:
    """Yaw (rad) of quaternions ``(*, 4)`` in ``(qx, qy, qz, qw)`` order."""
    q = np.asarray(q, float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quat_from_yaw(yaw) -> np.ndarray:
    """Quaternions ``(*, 4)`` (qx, qy, qz, qw) of rotations about z."""
    yaw = np.asarray(yaw, float)
    z = np.zeros_like(yaw)
    return np.stack([z, z, np.sin(yaw / 2), np.cos(yaw / 2)], -1)


def read_tum(path, with_strings: bool = False):
    """Reads a TUM trajectory.

    Args:
        path: the file.
        with_strings: also return each line's time exactly as written (scan file names
            use the same string).

    Returns:
        ``(times (N,), poses (N, 3))`` with poses ``(x, y, yaw)``, plus the time strings
        ``list[str]`` when ``with_strings``.

    Raises:
        DataError: missing file, a line without 8 columns, a non-number or non-finite value,
            timestamps that do not strictly increase (each names the file and line).
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
    strs, rows = [], []
    prev = after
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
            raise DataError(
                f"{where}:{no}: timestamp {cols[0]} does not increase (previous {prev!r})"
            )
        q = np.asarray(vals[4:8])
        if np.linalg.norm(q) < 1e-9:
            raise DataError(f"{where}:{no}: zero quaternion")
        prev = vals[0]
        strs.append(cols[0])
        rows.append(vals)
    arr = np.asarray(rows, float).reshape(-1, 8)
    poses = np.stack([arr[:, 1], arr[:, 2], yaw_from_quat(arr[:, 4:8])], -1)
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
