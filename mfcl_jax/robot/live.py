"""A dataset folder that is still being written (``mfcl localize --follow DIR``).

A recorder appends lines to ``odometry.tum`` (at any rate, on stamps of its own) and drops
``scans/<t>.pcd`` files. ``Follower`` polls the folder and hands out ever longer
``ScanSequence`` prefixes for ``Localizer.follow``: a scan joins, in time order, once its PCD
reads and the odometry's complete lines (ending with a newline) reach its stamp; its pose is
interpolated there (``io.timesync``, as for a finished folder). A scan stamped before the
odometry's first line, or older than a scan that already joined (it arrived late), is left
out and counted (``Follower.pending``).

A PCD that does not read yet (empty, truncated: the recorder is still writing it) is retried
at every poll. It is an error only when it cannot be a write in progress: its size and time
stamp have not changed for ``settle`` seconds while a later scan already exists. Appended
odometry lines are checked as ``read_tum`` checks a file (a bad complete line is an error
naming its line number).

The run ends when nothing new has arrived for ``idle_timeout`` seconds (or on Ctrl-C, which
the caller handles); ``Follower.pending`` then says what was still waiting. A scan that does
not read then, with later scans waiting behind it, is an error (``DataError``).

3-D clouds are cut as they arrive (``sources.planar.PlanarStream``: the floor is the median of
those seen so far). Windows are decided as they complete by the localizer's one jitted step,
whose buffers have fixed capacities, so a long run compiles nothing new.
"""

from __future__ import annotations

import bisect
import math
import os
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.pcd import pcd_fields, read_pcd
from mfcl_jax.io.timesync import TIME_TOL_S, interpolate_se2
from mfcl_jax.io.tum import parse_tum
from mfcl_jax.robot.signals import checkpoint
from mfcl_jax.sources.planar import PlanarParams, PlanarStream
from mfcl_jax.sources.sequence import ScanSequence

__all__ = ["Follower"]


class Follower:
    """Polls a growing dataset folder.

    Args:
        folder: the dataset folder (it must exist; odometry and scans may come later).
        planar: how scans become planar scans (2-D / 3-D, band, mount).
        idle_timeout: stop after this many seconds without new data.
        poll: seconds between polls.
        settle: an unreadable scan unchanged this long, with a later scan present, is an error.
        clock, sleep: time sources (tests).

    Attributes:
        n_odometry: complete odometry lines read so far.
        n_scans: scans that joined the sequence.
    """

    def __init__(
        self,
        folder,
        planar: PlanarParams | None = None,
        idle_timeout: float = 10.0,
        poll: float = 0.2,
        settle: float = 5.0,
        clock=time.monotonic,
        sleep=time.sleep,
    ):
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise DataError(f"{self.folder}: dataset folder not found")
        if not idle_timeout > 0:
            raise DataError(f"--idle-timeout must be > 0 s, got {idle_timeout!r}")
        self.odometry_path = self.folder / "odometry.tum"
        self.scan_dir = self.folder / "scans"
        self.idle_timeout, self.poll, self.settle = float(idle_timeout), float(poll), settle
        self._clock, self._sleep = clock, sleep
        self._planar = PlanarStream(planar or PlanarParams())
        self._xyz: bool | None = None
        self._offset, self._line = 0, 1
        self._times: list[float] = []  # odometry
        self._poses: list[np.ndarray] = []
        self._seen: dict[str, float] = {}  # scan file name -> stamp
        self._queue: list[tuple[float, Path]] = []  # scans not joined yet, in time order
        self._joined_t: list[float] = []  # stamps and poses of the scans read, in order
        self._joined_pose: list[np.ndarray] = []
        self._scans: list[np.ndarray] = []
        self._early = 0  # scans before the odometry's first stamp, left out
        self._late = 0  # scans older than one that already joined, left out
        self._failed: dict[Path, tuple] = {}  # unreadable scan -> (size, mtime, since, error)

    @property
    def n_odometry(self) -> int:
        return len(self._times)

    @property
    def n_scans(self) -> int:
        return len(self._scans)

    @property
    def dim(self) -> int | None:
        """2 or 3 once the first scan has been read."""
        return self._planar.dim

    def pending(self) -> list[str]:
        """What was still waiting, or was left out, when the run stopped; one sentence each."""
        out = []
        if self._queue:
            path = self._queue[0][1]
            why = self._failed.get(path)
            if why:
                what = f"unreadable: {why[3]}"
            elif not self._times:
                what = "no odometry line yet"
            else:
                what = f"the odometry's complete lines end at t={self._times[-1]:.6f} s"
            out.append(f"{self.scan_dir}: {len(self._queue)} scans still waiting, first {path} "
                       f"({what})")  # fmt: skip
        if self._early:
            out.append(f"{self.scan_dir}: {self._early} scans stamped before the odometry's "
                       f"first line (t={self._times[0]:.6f} s) were left out")  # fmt: skip
        if self._late:
            out.append(f"{self.scan_dir}: {self._late} scans arrived after a later scan had "
                       "joined and were left out")  # fmt: skip
        if self._planar.waiting:
            out.append(
                f"{self.folder}: {self._planar.waiting} 3-D clouds were waiting for a floor to "
                "be seen"
            )
        return out

    def _read_odometry(self) -> bool:
        """Parses the complete lines appended since the last poll; True when there were."""
        try:
            with self.odometry_path.open("rb") as f:
                f.seek(self._offset)
                data = f.read()
        except FileNotFoundError:
            return False
        end = data.rfind(b"\n")
        if end < 0:
            return False
        lines = data[: end + 1].decode("utf-8", "replace").splitlines()
        after = self._times[-1] if self._times else -math.inf
        t, poses, strs = parse_tum(lines, self.odometry_path, self._line, after)
        self._offset += end + 1
        self._line += len(lines)
        self._times += list(t)
        self._poses += list(poses)
        return len(strs) > 0

    def _list_scans(self) -> bool:
        """Adds the scan files that appeared since the last poll; True when there were."""
        try:
            names = [n for n in os.listdir(self.scan_dir) if n.endswith(".pcd")]
        except (FileNotFoundError, NotADirectoryError):
            return False
        new = False
        for name in names:
            if name in self._seen:
                continue
            path = self.scan_dir / name
            try:
                t = float(name[:-4])
            except ValueError:
                t = math.nan
            if not math.isfinite(t):
                raise DataError(f"{path}: a scan file is named by its time in seconds (e.g. "
                                f"1000.5.pcd), got {name[:-4]!r}")  # fmt: skip
            same = next((n for n, u in self._seen.items() if u == t), None)
            if same is not None:
                raise DataError(f"{path}: scan time t={t!r} is also the time of {same}")
            self._seen[name] = t
            self._queue.append((t, path))
            new = True
        if new:
            self._queue.sort(key=lambda e: e[0])
        return new

    def _read_scan(self, path: Path):
        """The points of ``path``, or ``None`` while it may still be being written."""
        try:
            if self._xyz is None:
                self._xyz = self._planar.params.dim != 2 and "z" in pcd_fields(path)
            pts = read_pcd(path, xyz=self._xyz)
        except DataError as e:
            try:
                st = path.stat()
            except FileNotFoundError:
                return None
            stamp = (st.st_size, st.st_mtime_ns)
            old = self._failed.get(path)
            since = old[2] if old and old[:2] == stamp else self._clock()
            self._failed[path] = (*stamp, since, str(e))
            later = len(self._queue) > 1
            if later and self._clock() - since >= self.settle:
                raise DataError(
                    f"{e} (unchanged for {self.settle:g} s while later scans arrived)"
                ) from None
            return None
        self._failed.pop(path, None)
        return pts

    def _read_scans(self) -> bool:
        """Joins the waiting scans in time order, up to the first one the odometry does not
        reach yet or that does not read yet."""
        grew = False
        while self._queue and self._times:
            t, path = self._queue[0]
            if t < self._times[0] - TIME_TOL_S or (self._joined_t and t <= self._joined_t[-1]):
                self._queue.pop(0)
                if self._joined_t and t <= self._joined_t[-1]:
                    self._late += 1
                else:
                    self._early += 1
                grew = True
                continue
            if t > self._times[-1] + TIME_TOL_S:
                break
            pts = self._read_scan(path)
            if pts is None:
                break
            self._queue.pop(0)
            i = bisect.bisect_left(self._times, t)
            lo, hi = max(i - 1, 0), min(i + 1, len(self._times))
            pose = interpolate_se2(self._times[lo:hi], np.asarray(self._poses[lo:hi]), [t])[0]
            self._joined_t.append(t)
            self._joined_pose.append(pose)
            self._scans += self._planar.push(pts, str(path))
            grew = True
        return grew

    def _check_blocked(self) -> None:
        """At the idle stop: a scan that still does not read, with later scans waiting behind
        it, is not a write in progress (nothing changed for ``idle_timeout`` s): an error."""
        if len(self._queue) > 1 and self._queue[0][1] in self._failed:
            path = self._queue[0][1]
            raise DataError(
                f"{self._failed[path][3]} (nothing new for {self.idle_timeout:g} s while "
                f"{len(self._queue) - 1} later scans waited behind it)"
            )

    def sequence(self) -> ScanSequence | None:
        """The scans that joined so far with their odometry (``None`` before the first)."""
        n = self.n_scans
        if n == 0:
            return None
        return ScanSequence(
            np.asarray(self._joined_t[:n]), list(self._scans), np.asarray(self._joined_pose[:n]),
            str(self.folder),
        )  # fmt: skip

    def prefixes(self) -> Iterator[ScanSequence]:
        """Yields the sequence each time it has grown; returns after ``idle_timeout`` s
        without new odometry or scans."""
        last = self._clock()
        while True:
            checkpoint()  # a stop whose exception was lost is raised here
            before = self.n_scans
            new_lines = self._read_odometry()
            new_files = self._list_scans()
            new_scans = self._read_scans()
            if new_lines or new_files or new_scans:
                last = self._clock()
            if self.n_scans > before:
                yield self.sequence()
            elif self._clock() - last >= self.idle_timeout:
                self._check_blocked()
                return
            else:
                self._sleep(self.poll)
