"""Keyframes and the windows' bounds: which scans count, and where each window starts and
ends along the odometry.

A scan is a keyframe once the odometry moved ``keyframe_spacing`` or turned
``keyframe_turn_deg`` since the last one (``keyframes``). Window ``k`` (1-based) starts at the
first keyframe whose travelled distance is at least ``step (k - 1)`` and ends at the first at
which the distance travelled inside the window reaches ``d_s`` (``window_bounds``), per
odometry segment (``segment_bounds``): no window straddles an odometry jump
(``odometry_segments``: a step no robot makes).
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.se2 import wrap_host

__all__ = [
    "keyframes",
    "travelled",
    "odometry_segments",
    "segment_bounds",
    "window_bounds",
    "JUMP_M",
    "JUMP_SPEED",
    "JUMP_DEG",
    "JUMP_RATE",
]


def keyframes(odometry, spacing: float = 0.20, turn_deg: float = 20.0) -> np.ndarray:
    """Indices ``(M,)`` of the scans kept as keyframes (the first scan is always kept)."""
    x = np.asarray(odometry, np.float64)
    return np.asarray(extend_keyframes(x, [0] if len(x) else [], 1, spacing, turn_deg), int)


def extend_keyframes(x, keep: list, start: int, spacing: float, turn_deg: float) -> list:
    """``keep`` (the keyframes among ``x[:start]``, a list) extended over ``x[start:]`` in
    place: the keyframes of a recording that grows, each scan looked at once (the rule is
    causal, so the result is ``keyframes(x)``)."""
    turn = np.deg2rad(turn_deg)
    if not keep and len(x):
        keep.append(0)
        start = 1
    for i in range(max(start, 1), len(x)):
        a = x[keep[-1]]
        dyaw = abs(wrap_host(x[i, 2] - a[2]))
        if np.hypot(*(x[i, :2] - a[:2])) >= spacing or dyaw >= turn:
            keep.append(i)
    return keep


def travelled(poses, segments=None) -> np.ndarray:
    """Cumulative planar distance along ``poses (T, 3)``; ``(T,)`` starting at 0.

    ``segments (T,)`` (``odometry_segments``): the steps between two segments (an odometry
    jump, not a move) count nothing, so the distance runs on from the run's start across them.
    """
    xy = np.asarray(poses, np.float64)[:, :2]
    step = np.hypot(*np.diff(xy, axis=0).T)
    if segments is not None:
        seg = np.asarray(segments).reshape(-1)
        step = np.where(seg[1:] == seg[:-1], step, 0.0)
    return np.concatenate([[0.0], np.cumsum(step)])


# An odometry restart (the frame re-zeroed mid-run) shows as a step between consecutive
# keyframes that no robot makes: longer than JUMP_M + JUMP_SPEED * dt, or a turn larger than
# JUMP_DEG + JUMP_RATE * dt. The real logs' largest keyframe steps (orebro: 3.2 m in 1 s;
# seattle: 81 deg) and the simulator's pivots (126 deg in 0.5 s) stay inside. Poses before and
# after a jump are in incommensurable frames, so windows never straddle one and the decision
# layer starts over after it. A restart close to where the odometry frame began (within
# about 2.75 m at 2 Hz keyframes) is not a jump by this rule and goes unnoticed.
JUMP_M, JUMP_SPEED = 1.0, 3.5  # m, m/s
JUMP_DEG, JUMP_RATE = 150.0, 60.0  # deg, deg/s


def odometry_segments(poses, times) -> np.ndarray:
    """``(T,)`` segment id of each pose: 0, plus one after every odometry jump."""
    x = np.asarray(poses, np.float64).reshape(-1, 3)
    t = np.asarray(times, np.float64).reshape(-1)
    if len(x) < 2:
        return np.zeros(len(x), np.int64)
    dt = np.abs(np.diff(t))
    dt = np.where(np.isfinite(dt), dt, 0.0)
    step = np.hypot(*np.diff(x[:, :2], axis=0).T)
    turn = np.rad2deg(np.abs(wrap_host(np.diff(x[:, 2]))))
    jump = (step > JUMP_M + JUMP_SPEED * dt) | (turn > JUMP_DEG + JUMP_RATE * dt)
    return np.concatenate([[0], np.cumsum(jump)]).astype(np.int64)


def segment_bounds(poses, segments, d_s: float, step: float = 2.0) -> np.ndarray:
    """``window_bounds`` of each odometry segment (``segments (T,)``: ``Windows.segments``),
    in order: no window straddles a jump."""
    seg = np.asarray(segments).reshape(-1)
    out = []
    for s_id in np.unique(seg):
        idx = np.flatnonzero(seg == s_id)
        b = window_bounds(travelled(np.asarray(poses)[idx]), d_s, step)
        out.append(b + idx[0])
    return np.concatenate(out).reshape(-1, 2) if out else np.zeros((0, 2), np.int64)


def window_bounds(s, d_s: float, step: float = 2.0) -> np.ndarray:
    """``(K, 2)`` inclusive ``(first, last)`` indices of the windows over travelled ``s (T,)``."""
    s = np.asarray(s, dtype=np.float64)
    if not d_s > 0:
        raise ValueError(f"d_s must be > 0, got d_s={d_s!r}")
    eps = 1e-6
    out = []
    k = 0
    while True:
        j0 = int(np.searchsorted(s, step * k - eps, side="left"))
        if j0 >= len(s):
            break
        j1 = int(np.searchsorted(s, s[j0] + d_s - eps, side="left"))
        if j1 >= len(s):
            break
        out.append((j0, j1))
        k += 1
    return np.asarray(out, dtype=np.int64).reshape(-1, 2)
