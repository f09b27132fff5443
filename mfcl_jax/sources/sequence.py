"""Scan sequences: what the localizer consumes (times, sensor-frame scans, odometry in L).

A ``ScanSequence`` comes from a dataset folder, a ROS bag or a CARMEN log; ``windows.cut``
thins it to keyframes (``windows.keyframes``) and cuts it into submaps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.timesync import odometry_at

__all__ = ["ScanSequence", "from_dataset", "from_bag", "from_carmen"]


@dataclass(frozen=True, eq=False)
class ScanSequence:
    """Scans with their odometry.

    Attributes:
        times: ``(N,)`` increasing scan times (s).
        scans: ``N`` arrays ``(n_i, 2)``, points in the sensor frame.
        odometry: ``(N, 3)`` sensor poses in L.
        source: where it came from (for messages).
    """

    times: np.ndarray
    scans: list
    odometry: np.ndarray
    source: str = "<memory>"

    def __post_init__(self):
        t = np.asarray(self.times, np.float64).reshape(-1)
        x = np.asarray(self.odometry, np.float64).reshape(-1, 3)
        if not (len(t) == len(x) == len(self.scans)):
            raise DataError(
                f"{self.source}: {len(t)} times, {len(self.scans)} scans and {len(x)} "
                "odometry poses must agree"
            )
        if len(t) == 0:
            raise DataError(f"{self.source}: no scans")
        if not np.all(np.isfinite(t)) or not np.all(np.isfinite(x)):
            bad = int(np.flatnonzero(~np.isfinite(t) | ~np.all(np.isfinite(x), 1))[0])
            raise DataError(f"{self.source}: non-finite time or odometry at scan #{bad}")
        if np.any(np.diff(t) <= 0):
            bad = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise DataError(f"{self.source}: scan times must increase (scan #{bad}, t={t[bad]})")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "odometry", x)

    def __len__(self) -> int:
        return len(self.times)

    def subset(self, idx) -> ScanSequence:
        idx = np.asarray(idx, int)
        return ScanSequence(
            self.times[idx], [self.scans[i] for i in idx], self.odometry[idx], self.source
        )


def from_dataset(ds) -> ScanSequence:
    """The scan sequence of a loaded ``io.Dataset`` (ground truth is not carried)."""
    return ScanSequence(ds.times, list(ds.scans), ds.odometry, str(ds.folder))


def from_bag(bag, source: str = "<bag>") -> ScanSequence:
    """The scan sequence of ``io.read_bag``'s result."""
    return ScanSequence(bag.times, list(bag.scans), bag.odometry, source)


def from_carmen(log, odometry=None, source: str = "<carmen>") -> ScanSequence:
    """A CARMEN log's scans with ``odometry`` (default the log's own odometry columns).

    Lines whose time goes backwards are dropped (real logs have a few). The odometry, one
    pose per FLASER line at its stamp, is looked up at the scan stamps by
    ``io.timesync.odometry_at`` like every input's odometry (same checks, yaw wrapped).

    Args:
        log: ``io.CarmenLog``.
        odometry: ``(N, 3)`` poses, one per FLASER line, or None for ``log.odometry``.
        source: name for messages.

    Raises:
        DataError: ``odometry`` with another number of rows than the log has lines.
    """
    t = np.asarray(log.times, np.float64)
    keep = np.concatenate([[True], t[1:] > np.maximum.accumulate(t)[:-1]])
    odo = log.odometry if odometry is None else np.asarray(odometry, np.float64)
    if len(odo) != len(t):
        raise DataError(f"{source}: {len(odo)} odometry poses for {len(t)} FLASER lines")
    idx = np.flatnonzero(keep)
    _, poses = odometry_at(t[idx], odo[idx], t[idx], source)
    return ScanSequence(t[idx], [log.scans[i] for i in idx], poses, source)
