"""A dataset folder that is still being written (``mfcl localize --follow DIR``).

A recorder appends lines to ``odometry.tum`` and drops ``scans/<t>.pcd`` files. ``Follower``
polls the folder and hands out ever longer ``ScanSequence`` prefixes for
``Localizer.follow``: scan ``i`` joins once its odometry line is complete (ends with a
newline) and its PCD reads. Scans join in odometry order, so a prefix never has a gap.

A PCD that does not read yet (empty, truncated: the recorder is still writing it) is retried
at every poll. It is an error only when it cannot be a write in progress: its size and time
stamp have not changed for ``settle`` seconds while a later scan already exists. Appended
odometry lines are checked as ``read_tum`` checks a file (a bad complete line is an error
naming its line number).

The run ends when nothing new has arrived for ``idle_timeout`` seconds (or on Ctrl-C, which
the caller handles); ``Follower.pending`` then says what was still waiting.

3-D clouds are cut as they arrive (``sources.planar.PlanarStream``: the floor is the median of
those seen so far). The streaming decision's buffers double as the run grows (8, 16, 32, ...
windows): each doubling compiles the decision kernel once, a pause of a few seconds at windows
9, 17, 33, ... on the first run, a trace and a cache read (about a second) afterwards.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.pcd import pcd_fields, read_pcd
from mfcl_jax.io.tum import parse_tum
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
        self._times: list[float] = []
        self._strs: list[str] = []
        self._poses: list[np.ndarray] = []
        self._read = 0  # odometry lines whose scan has been read
        self._scans: list[np.ndarray] = []
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
        """What was still waiting when the run stopped, one sentence each."""
        out = []
        waiting = self.n_odometry - self._read
        if waiting:
            path = self._scan_path(self._read)
            why = self._failed.get(path)
            what = f"unreadable: {why[3]}" if why else "no such file yet"
            out.append(
                f"{self.odometry_path}: {waiting} odometry lines still had no scan, first "
                f"{path} ({what})"
            )
        if self._planar.waiting:
            out.append(
                f"{self.folder}: {self._planar.waiting} 3-D clouds were waiting for a floor to "
                "be seen"
            )
        return out

    def _scan_path(self, i: int) -> Path:
        return self.scan_dir / f"{self._strs[i]}.pcd"

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
        self._strs += strs
        return len(strs) > 0

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
            nxt = self._read + 1
            later = nxt < self.n_odometry and self._scan_path(nxt).exists()
            if later and self._clock() - since >= self.settle:
                raise DataError(
                    f"{e} (unchanged for {self.settle:g} s while later scans arrived)"
                ) from None
            return None
        self._failed.pop(path, None)
        return pts

    def _read_scans(self) -> bool:
        """Reads the scans of the odometry lines in order, up to the first missing one."""
        grew = False
        while self._read < self.n_odometry:
            path = self._scan_path(self._read)
            if not path.is_file():
                break
            pts = self._read_scan(path)
            if pts is None:
                break
            self._scans += self._planar.push(pts, str(path))
            self._read += 1
            grew = True
        return grew

    def sequence(self) -> ScanSequence | None:
        """The scans that joined so far with their odometry (``None`` before the first)."""
        n = self.n_scans
        if n == 0:
            return None
        return ScanSequence(
            np.asarray(self._times[:n]), list(self._scans), np.asarray(self._poses[:n]),
            str(self.folder),
        )  # fmt: skip

    def prefixes(self) -> Iterator[ScanSequence]:
        """Yields the sequence each time it has grown; returns after ``idle_timeout`` s
        without new odometry or scans."""
        last = self._clock()
        while True:
            before = self.n_scans
            new_lines = self._read_odometry()
            new_scans = self._read_scans()
            if new_lines or new_scans:
                last = self._clock()
            if self.n_scans > before:
                yield self.sequence()
            elif self._clock() - last >= self.idle_timeout:
                return
            else:
                self._sleep(self.poll)
