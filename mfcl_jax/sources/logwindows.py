"""Windows of a log: stretches of travel, spread over it, and the scans their maps leave out.

A window is ``length_m`` metres of travel: it starts at a scan and ends at the first scan at
least ``length_m`` further on. ``plan_windows`` spreads ``n_windows`` of them evenly over a log
without sharing a scan, and names the scans each window's held-out map must leave out: the
window's own and those within ``margin_m`` of travel before or after it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EXCLUDE_MARGIN_M", "LogWindow", "plan_windows"]

# The neighbours of a window's end scans see nearly the window's view; a prior map is made at
# another time, so they are left out too.
EXCLUDE_MARGIN_M = 2.0


@dataclass(frozen=True)
class LogWindow:
    """One window of a log, as ranges of its scan (FLASER line) indices.

    Attributes:
        number: position among the log's windows (0, 1, ...).
        first, last: the window's first and last scan (inclusive).
        held_out: ``(first, last)`` inclusive range of scans left out of its map (the window
            plus the margin).
        start_m: travel (m) from the log's start to the window's first scan.
        travel_m: travel (m) from the window's first to its last scan.
    """

    number: int
    first: int
    last: int
    held_out: tuple[int, int]
    start_m: float
    travel_m: float

    @property
    def scans(self) -> np.ndarray:
        """``(n,)`` the window's scan indices."""
        return np.arange(self.first, self.last + 1)


def plan_windows(
    travel, n_windows: int, length_m: float, where: str, margin_m: float = EXCLUDE_MARGIN_M
) -> list[LogWindow]:
    """Chooses ``n_windows`` disjoint windows of ``length_m`` metres, spread over a log.

    Nominal starts are spaced evenly from the log's start to the last start that leaves
    ``length_m`` of travel; each window begins at the first scan at or after its nominal start
    and after the previous window's last scan. Should that run out of log, the windows are
    packed from the start instead.

    Args:
        travel: ``(N,)`` non-decreasing travel (m) at each scan.
        n_windows: how many windows (>= 1).
        length_m: travel per window (m, > 0).
        where: the log's name (for messages).
        margin_m: travel (m) before and after a window also left out of its map.

    Returns:
        ``n_windows`` ``LogWindow``s in log order.

    Raises:
        ValueError: bad arguments, or a log that cannot hold the request.
    """
    s = np.asarray(travel, np.float64)
    if isinstance(n_windows, bool) or not isinstance(n_windows, int | np.integer) or n_windows < 1:
        raise ValueError(f"log {where!r}: n_windows must be an integer >= 1, got {n_windows!r}")
    if not length_m > 0:
        raise ValueError(f"log {where!r}: length_m must be > 0, got {length_m!r}")

    def end_of(i0: int) -> int | None:
        i1 = int(np.searchsorted(s, s[i0] + length_m - 1e-9, "left"))
        return i1 if i1 < len(s) else None

    packed, i0 = [], 0
    while i0 < len(s) and (i1 := end_of(i0)) is not None:
        packed.append((i0, i1))
        i0 = i1 + 1
    if len(packed) < n_windows:
        raise ValueError(
            f"log {where!r} is too short: {s[-1]:.1f} m of travel over {len(s)} scans holds "
            f"{len(packed)} disjoint window(s) of {length_m:g} m; requested {n_windows}"
        )
    last_start = s[int(np.searchsorted(s, s[-1] - length_m + 1e-9, "right")) - 1]
    spread, prev = [], -1
    for k in range(n_windows):
        a = last_start * k / (n_windows - 1) if n_windows > 1 else 0.0
        i0 = max(int(np.searchsorted(s, a - 1e-9, "left")), prev + 1)
        i1 = end_of(i0) if i0 < len(s) else None
        if i1 is None:
            spread = packed[:n_windows]
            break
        spread.append((i0, i1))
        prev = i1
    out = []
    for k, (i0, i1) in enumerate(spread):
        h0 = int(np.searchsorted(s, s[i0] - margin_m, "left"))
        h1 = int(np.searchsorted(s, s[i1] + margin_m, "right")) - 1
        out.append(LogWindow(k, i0, i1, (h0, h1), float(s[i0]), float(s[i1] - s[i0])))
    return out
