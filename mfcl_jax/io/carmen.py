"""CARMEN logs: ``FLASER n r1..rn x y theta odom_x odom_y odom_theta timestamp host logger_t``.

The ``x y theta`` of a FLASER line is the laser pose of the log (SLAM-corrected in the
``*-corrected`` logs). Beams span a 180 deg field of view, centred on the sensor's x axis:
an odd count ``n`` places the first and last beams at -90 and +90 deg (step ``180/(n-1)``),
an even count steps ``180/n`` from -90 deg (the classic 180-beam, 1 deg scanner). Both
conventions give the sharpest maps of the four corrected logs in ``shared/data/laser`` (Intel 180
beams, Freiburg 101 360, Orebro 181, Seattle 361): shifting the beams by 0.1 deg or scaling the
step by 0.5 % blurs every map.

Dropped readings: <= 0, at or beyond ``max_range``, and the SICK status codes that stand for
"no return" (the top 9 values of the scanner's range word: 81.83..81.91 m in centimetre mode,
32.759..32.767 m in millimetre mode, as the Orebro log writes them; a real echo never lands
there).

Units: readings are metres; a log whose first FLASER lines (``io.units.N_FIRST``) have a
median positive reading above ``io.units.MM_MEDIAN_RANGE`` (200) is refused as millimetres,
before ``max_range`` would silently drop every reading.

Odometry: each FLASER line carries the odometry at its own stamp (the CARMEN logger
interpolates it there), so the log's ``ODOM`` lines (their own rate; in the four real logs
they go back in time 123 to 1498 times) are not read. ``sources.sequence.from_carmen`` looks
the FLASER odometry up at the scan stamps with ``io.timesync.odometry_at``, the code every
other input's odometry goes through.

Timestamps: some logs have no clock (the Orebro log writes 0 on every line). Such a log is an
error unless ``untimed_period`` is given, which numbers its lines ``0, period, 2 period, ...``
(``CarmenLog.timed`` is then False). Plain or gzip-compressed files.
"""

from __future__ import annotations

import gzip
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.units import N_FIRST, check_metres

__all__ = ["CarmenLog", "read_carmen", "beam_angles", "NO_RETURN_CODES"]

# ``(lo, hi)`` (m) bands of SICK "no return" status codes (see module doc).
NO_RETURN_CODES = ((81.83, 81.91), (32.759, 32.767))


@dataclass(frozen=True, eq=False)
class CarmenLog:
    """Laser scans of a CARMEN log.

    Attributes:
        times: ``(N,)`` FLASER timestamps (s).
        scans: ``N`` arrays ``(n_i, 2)``, points in the sensor frame (m).
        poses: ``(N, 3)`` the FLASER laser poses ``(x, y, theta)``.
        odometry: ``(N, 3)`` the FLASER odometry poses (equal to ``poses`` in corrected logs).
        time_reversals: how many FLASER timestamps are earlier than the one before (real
            logs have a few; the lines stay in file order).
        timed: False when the log has no clock and ``times`` number the lines.
    """

    times: np.ndarray
    scans: list[np.ndarray]
    poses: np.ndarray
    odometry: np.ndarray
    time_reversals: int = 0
    timed: bool = True

    def __len__(self) -> int:
        return len(self.times)


def beam_angles(n: int, fov: float = math.pi) -> np.ndarray:
    """Angles (rad) of ``n`` beams over ``fov`` centred on the x axis (see module doc)."""
    step = fov / (n - 1) if n % 2 == 1 else fov / n
    return -fov / 2 + step * np.arange(n)


def _no_return(r: np.ndarray) -> np.ndarray:
    out = np.zeros(r.shape, bool)
    for lo, hi in NO_RETURN_CODES:
        out |= (r >= lo - 5e-4) & (r <= hi + 5e-4)
    return out


def read_carmen(
    path,
    max_range: float = 50.0,
    fov: float = math.pi,
    strict_time: bool = False,
    untimed_period: float | None = None,
) -> CarmenLog:
    """Reads the FLASER lines of a CARMEN log (``.log`` or ``.log.gz``).

    Args:
        path: the log.
        max_range: readings at or beyond this (m) are no-returns.
        fov: field of view (rad) of the beams.
        strict_time: raise on a timestamp earlier than the previous one; otherwise such
            lines are kept in file order and counted in ``time_reversals``.
        untimed_period: for a log whose FLASER timestamps are all equal (no clock): the time
            step (s) that numbers its lines; ignored for a log with a clock.

    Raises:
        DataError: missing file, a FLASER line with too few fields or non-numbers, times that
            go backwards (``strict_time``), a log without a clock and no ``untimed_period``,
            a log without FLASER lines, readings in millimetres (each names the file and
            line).
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    opener = gzip.open if path.suffix == ".gz" else open
    times, scans, poses, odom, first = [], [], [], [], []
    reversals = 0
    angles: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    try:
        with opener(path, "rt") as fh:
            for no, line in enumerate(fh, 1):
                if not line.startswith("FLASER"):
                    continue
                cols = line.split()
                try:
                    n = int(cols[1])
                    vals = np.asarray(cols[2 : 2 + n + 7], float)
                except (ValueError, IndexError):
                    raise DataError(f"{path}:{no}: malformed FLASER line") from None
                if n < 2 or len(vals) != n + 7:
                    raise DataError(
                        f"{path}:{no}: FLASER with n={n} needs {n + 7} numbers after n, "
                        f"got {len(vals)}"
                    )
                if not np.all(np.isfinite(vals[n:])):
                    raise DataError(f"{path}:{no}: non-finite pose or timestamp")
                t = float(vals[n + 6])
                if times and t < times[-1]:
                    if strict_time:
                        raise DataError(f"{path}:{no}: timestamp {t} before previous {times[-1]}")
                    reversals += 1
                if n not in angles:
                    a = beam_angles(n, fov)
                    angles[n] = (np.cos(a), np.sin(a))
                c, s = angles[n]
                r = vals[:n]
                if len(first) < N_FIRST:
                    first.append((no, r[np.isfinite(r) & (r > 0)]))
                ok = np.isfinite(r) & (r > 0) & (r < max_range) & ~_no_return(r)
                scans.append(np.stack([r[ok] * c[ok], r[ok] * s[ok]], -1))
                poses.append(vals[n : n + 3])
                odom.append(vals[n + 3 : n + 6])
                times.append(t)
    except (OSError, EOFError, UnicodeDecodeError) as e:
        raise DataError(f"{path}: cannot read ({e})") from None
    if not times:
        raise DataError(f"{path}: no FLASER lines")
    check_metres([r[:, None] for _, r in first], [f"{path}:{no}" for no, _ in first], str(path))
    t = np.asarray(times)
    timed = len(t) == 1 or bool(np.ptp(t) > 0)
    if not timed:
        if untimed_period is None or not untimed_period > 0:
            raise DataError(
                f"{path}: all {len(t)} FLASER timestamps equal {t[0]} (a log without a clock); "
                f"pass untimed_period > 0 to number its lines (got {untimed_period!r})"
            )
        t = untimed_period * np.arange(len(t), dtype=np.float64)
    return CarmenLog(
        t,
        scans,
        np.asarray(poses).reshape(-1, 3),
        np.asarray(odom).reshape(-1, 3),
        reversals,
        timed,
    )
