"""Ground truth for the raw Intel bag: its scans matched to the corrected Intel log's scans.

The corrected CARMEN log keeps a subsample of the bag's scans (same readings, SLAM-corrected
poses) with times shifted by a constant offset. ``bag_ground_truth`` finds that offset and
checks every match scan by scan; ``truth_at_scans`` then gives a true pose at any bag scan: the
nearest well-matched corrected pose, moved by the bag odometry's motion since it (the gaps are a
second or two, so the odometry's drift over them is a few centimetres at most).
"""

from __future__ import annotations

import numpy as np

from mfcl_jax import se2

__all__ = ["bag_ground_truth", "truth_at_scans"]


def bag_ground_truth(bag, log, tol: float = 0.02):
    """Matches the corrected log's scans to the bag's scans.

    The corrected log's times are the bag's scan stamps minus a constant offset. The offset is
    the one (among bag stamp minus the first log time, over the first 400 bag scans) that
    matches the most log times within ``tol``; each match is then checked scan by scan (the
    log scan's points must coincide with the bag scan's within 1 cm).

    Args:
        bag: ``io.BagScans`` of the raw bag.
        log: ``io.CarmenLog`` of the corrected log.
        tol: largest time difference (s) of a match.

    Returns:
        ``(offset, bag_index (M,), log_index (M,), agree (M,))`` with ``agree`` the fraction
        of the log scan's points that coincide with the bag scan's.
    """
    bt = bag.times
    best = (-1, 0.0)
    for j in range(min(400, len(bt))):
        off = bt[j] - log.times[0]
        k = np.clip(np.searchsorted(bt, log.times + off), 1, len(bt) - 1)
        d = np.minimum(abs(bt[k] - log.times - off), abs(bt[k - 1] - log.times - off))
        n = int(np.sum(d < tol))
        if n > best[0]:
            best = (n, off)
    off = best[1]
    k = np.clip(np.searchsorted(bt, log.times + off), 1, len(bt) - 1)
    k = np.where(abs(bt[k - 1] - log.times - off) < abs(bt[k] - log.times - off), k - 1, k)
    ok = abs(bt[k] - log.times - off) < tol
    li, bi = np.flatnonzero(ok), k[ok]

    def radii(p):
        return np.round(np.hypot(p[:, 0], p[:, 1]) * 1000).astype(np.int64)

    agree = np.array(
        [
            np.mean(np.isin(radii(log.scans[i]), radii(bag.scans[b])))
            if len(bag.scans[b]) and len(log.scans[i])
            else 0.0
            for b, i in zip(bi, li, strict=True)
        ]
    )
    return off, bi, li, agree


def truth_at_scans(bag, sel, bag_index, log_poses):
    """True poses at bag scans from matched corrected poses.

    Args:
        bag: ``io.BagScans``.
        sel: ``(K,)`` indices of the bag scans that need a true pose.
        bag_index: ``(M,)`` increasing indices of bag scans with a trusted corrected pose.
        log_poses: ``(M, 3)`` those corrected poses.

    Returns:
        ``(poses (K, 3), gap (K,))``: the true poses and the time (s) from each scan to the
        matched scan its pose was carried from.
    """
    sel = np.asarray(sel, int)
    mt = bag.times[bag_index]
    t = bag.times[sel]
    j = np.clip(np.searchsorted(mt, t), 1, len(mt) - 1)
    j = np.where(abs(mt[j - 1] - t) < abs(mt[j] - t), j - 1, j)
    rel = np.asarray(se2.between(bag.odometry[bag_index[j]], bag.odometry[sel]), np.float64)
    poses = np.asarray(se2.compose(np.asarray(log_poses)[j], rel), np.float64)
    return poses, np.abs(mt[j] - t)
