"""Where and why a ``mfcl localize`` run was split into odometry segments: one line on stderr
at the first window of every new segment.

An odometry jump (a restart of the odometry, a relocalization of an LIO) puts the poses after
it in a frame unrelated to the one before, so no window straddles it and the decision layer
starts over (``windows``: ``Windows.segments``). A jump is found by one of two tests:

- the input odometry's step test (``windows.odometry_segments`` over the keyframes): a step
  between consecutive keyframes longer or sharper than a robot moves in that time;
- the LiDAR odometry's jump test (``windows.odometry``, when scan matching is on): the input's
  step does not fit the scans while a different step fits them well.

The windows carry only their segment; the input's test is repeated here over the keyframes of
the sequence, and a new segment that it does not explain was started by the LiDAR test.
"""

from __future__ import annotations

import math

import numpy as np

from mfcl_jax.se2 import wrap_host

__all__ = ["Splits"]


class Splits:
    """Follows the windows of one run and says where a new odometry segment starts.

    Args:
        params: the run's ``WindowParams`` (its keyframe spacing and turn).
        source: the input's name, for the message.
    """

    def __init__(self, params, source: str):
        self.params = params
        self.source = str(source)
        self._prev: tuple | None = None  # (segment, last keyframe's scan, t) of the last window
        self.splits = 0  # segments started after the first window (notes given)

    def note(self, seq, k: int, segment: int, t: float, first=None, last=None) -> str | None:
        """The line for window ``k`` (``None`` when it stays in the segment before).

        Args:
            seq: the ``ScanSequence`` that holds the window (a live run: the prefix so far),
                or a function that returns it (called only when the segment changes).
            k: the window's index over the recording; ``segment`` its odometry segment;
                ``t`` the time of its last scan.
            first, last: indices into ``seq`` of the window's first and last scan (a
                batch knows only ``t``: the jump is then placed between two windows' times).
        """
        prev, self._prev = self._prev, (int(segment), last, float(t))
        before = 0 if prev is None else prev[0]
        if int(segment) == before:
            return None
        self.splits += 1
        seq = seq() if callable(seq) else seq
        why = self._why(seq, prev, int(segment) - before, float(t), first)
        skipped = int(segment) - before - 1
        if skipped:
            why += (f"; {skipped} segment{'s' if skipped > 1 else ''} in between held no "
                    "complete window")  # fmt: skip
        return (
            f"mfcl: {self.source}: odometry segment {segment} starts at window {k}: {why}. "
            "The decision layer starts over there (poses before and after a jump are in "
            "unrelated frames; no window straddles one)"
        )

    def _why(self, seq, prev, n: int, t: float, first) -> str:
        from mfcl_jax import windows as W

        p = self.params
        kf = W.keyframes(seq.odometry, p.keyframe_spacing, p.keyframe_turn_deg)
        times = np.asarray(seq.times, np.float64)[kf]
        raw = np.asarray(seq.odometry, np.float64)[kf]
        seg_in = W.odometry_segments(raw, times)
        # Keyframes that may start the segment: after the last window's last keyframe, up to
        # this window's first (or, knowing its time only, its last).
        if prev is not None and prev[1] is not None:
            a = int(np.searchsorted(kf, prev[1]))
        elif prev is not None:
            a = int(np.searchsorted(times, prev[2], side="right")) - 1
        else:
            a = 0
        b = (int(np.searchsorted(kf, first)) if first is not None
             else int(np.searchsorted(times, t, side="right")) - 1)  # fmt: skip
        cand = range(max(a + 1, 1), min(b, len(kf) - 1) + 1)
        given = [j for j in cand if seg_in[j] != seg_in[j - 1]]
        parts = [self._jump(j, kf, times, raw, "the input odometry's step test") for j in given]
        lidar = n - len(given)
        if lidar > 0 and first is not None and b >= 1 and b not in given:
            parts.append(self._jump(b, kf, times, raw, "the LiDAR odometry's jump test"))
            lidar -= 1
        if lidar > 0:
            lo = f"t={times[a]:.2f} s" if prev is not None else "the start"
            parts.append(
                f"{lidar} jump{'s' if lidar > 1 else ''} between {lo} and t={t:.2f} s found by "
                "the LiDAR odometry's jump test (the input odometry's step does not fit the "
                "scans; a different step does)"
            )
        return "; ".join(parts)

    @staticmethod
    def _jump(j: int, kf, times, raw, test: str) -> str:
        step = math.hypot(*(raw[j, :2] - raw[j - 1, :2]))
        dyaw = float(wrap_host(raw[j, 2] - raw[j - 1, 2]))
        dt = times[j] - times[j - 1]
        what = (f"the input odometry moves {step:.2f} m and turns {math.degrees(abs(dyaw)):.0f} "
                f"deg in {dt:.2f} s")  # fmt: skip
        if "LiDAR" in test:
            what += ", which the scans do not fit (a different step fits them well)"
        else:
            what += ", more than a robot moves in that time"
        return f"an odometry jump at t={times[j]:.2f} s (scan {int(kf[j])}) found by {test}: {what}"
