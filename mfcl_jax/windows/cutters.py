"""Cutting beyond one sequence at a time: many sequences, each one's LiDAR odometry refined
once (``cut_many``; batched on an accelerator), and a recording that grows, window by window
as each completes (``Cutter``). Both give ``submaps.cut``'s windows."""

from __future__ import annotations

import jax
import numpy as np

from mfcl_jax.windows.keyframes import (
    extend_keyframes,
    keyframes,
    odometry_segments,
    segment_bounds,
)
from mfcl_jax.windows.odometry import LIVE_CHUNK, Odometer, extend_many
from mfcl_jax.windows.submaps import WindowParams, Windows, _windows, window

__all__ = ["cut_many", "Cutter"]


def cut_many(items, rows: int = 1, together: bool | None = None) -> list[Windows]:
    """``cut(seq, params)`` of every ``(seq, params)`` pair, the LiDAR odometry of each
    distinct sequence refined once (shared by its ``d_s`` values). In turn, equal to cutting
    one by one; together, to float32 rounding (a pose within about 1e-9 m).

    ``together``: all sequences in one batched kernel (``odometry.extend_many``; ``rows``: its
    least batch, so that calls with fewer sequences share its compilation), or each sequence
    in turn (one compilation for all). Default: together on an accelerator, in turn on a CPU,
    where the batched kernel was measured slower (12 benchmark recordings: 16.5 s against
    12.6 s; among other things, the batch runs as long as its longest sequence).
    """
    items = list(items)
    if together is None:
        together = jax.default_backend() != "cpu"
    keys = {}
    for seq, p in items:
        k = (id(seq), p.keyframe_spacing, p.keyframe_turn_deg, p.scan_match)
        keys.setdefault(k, (seq, p))
    kfs, odos = {}, {}
    groups: dict = {}
    for k, (seq, p) in keys.items():
        kf = keyframes(seq.odometry, p.keyframe_spacing, p.keyframe_turn_deg)
        raw = np.asarray(seq.odometry, np.float64)[kf]
        kfs[k] = (kf, raw, odometry_segments(raw, np.asarray(seq.times)[kf]))
        groups.setdefault(p.scan_match, []).append(k)
    for sm, ks in groups.items():
        meters = [Odometer(sm) for _ in ks]
        scans = [[keys[k][0].scans[i] for i in kfs[k][0]] for k in ks]
        odo, seg = [kfs[k][1] for k in ks], [kfs[k][2] for k in ks]
        if together:
            poses = extend_many(meters, scans, odo, seg, rows=rows)
        else:
            poses = [extend_many([m], [s], [o], [g])[0]
                     for m, s, o, g in zip(meters, scans, odo, seg, strict=True)]  # fmt: skip
        for k, m, po in zip(ks, meters, poses, strict=True):
            odos[k] = (po, m.segments)
    out = []
    for seq, p in items:
        k = (id(seq), p.keyframe_spacing, p.keyframe_turn_deg, p.scan_match)
        out.append(_windows(seq, p, kfs[k][0], *odos[k]))
    return out


class Cutter:
    """The windows of a growing recording, each as soon as it is complete.

    ``feed(seq)`` takes the recording so far (each call's ``seq`` extends the previous one)
    and returns the windows completed since the last call, one ``Windows`` each. The LiDAR
    odometry is extended ``scan_match.chunk`` keyframes at a time, so a robot sees its first
    window after the first few keyframes, not after the whole recording; windows are causal,
    so the result equals ``cut`` of the final sequence.

    ``live``: the recording grows a few scans at a time (a robot), so the LiDAR odometry runs
    ``odometry.LIVE_CHUNK`` keyframes per kernel call instead of ``scan_match.chunk`` (the
    same poses, a fraction of the time per new keyframe).

    Attributes:
        odometer: the ``Odometer`` (its ``poses`` and ``segments`` cover the keyframes so far).
        n_windows: windows emitted so far.
    """

    def __init__(self, params: WindowParams | None = None, live: bool = False):
        self.params = params or WindowParams()
        self.live = live
        self.odometer = Odometer(self.params.scan_match)
        self.n_windows = 0
        self._kf: list[int] = []  # keyframes of the scans looked at so far (``_seen``)
        self._seen = 0

    def estimate(self, seq) -> int:
        """Windows of ``seq`` by the input odometry alone (the LiDAR odometry's jump test
        may split a segment and change the count): a progress bar's total."""
        p = self.params
        kf = keyframes(seq.odometry, p.keyframe_spacing, p.keyframe_turn_deg)
        raw = np.asarray(seq.odometry, np.float64)[kf]
        seg = odometry_segments(raw, np.asarray(seq.times)[kf])
        return len(segment_bounds(raw, seg, p.d_s, p.step))

    def feed(self, seq):
        """Yields the windows of ``seq`` completed since the last call (one ``Windows`` each,
        with the keyframes, odometry and segments so far)."""
        p = self.params
        x = np.asarray(seq.odometry, np.float64)
        extend_keyframes(x, self._kf, self._seen, p.keyframe_spacing, p.keyframe_turn_deg)
        self._seen = len(x)
        kf = np.asarray(self._kf, int)
        raw = x[kf]
        seg_in = odometry_segments(raw, np.asarray(seq.times)[kf])
        odo = self.odometer
        step = LIVE_CHUNK if self.live else p.scan_match.chunk
        while len(odo) < len(kf):
            a = len(odo)
            b = min(a + step, len(kf))
            odo.extend([seq.scans[i] for i in kf[a:b]], raw[a:b], seg_in[a:b], chunk=step)
            w = _windows(seq, p, kf[:b], odo.poses[:b], odo.segments[:b], start=self.n_windows)
            for k in range(len(w)):
                yield window(w, k)
            self.n_windows += len(w)
