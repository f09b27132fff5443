"""Ground truth for the raw Intel bag: its scans matched to the corrected Intel log's scans.

The corrected CARMEN log keeps a subsample of the bag's scans (same readings, SLAM-corrected
poses) with times shifted by a constant offset. ``bag_ground_truth`` finds that offset and
checks every match scan by scan; ``truth_at_scans`` then gives a true pose at any bag scan from
the two well-matched corrected poses around it (about 3 s apart): each is carried to the scan by
the bag odometry's motion since it, and the two carried poses are blended by time, so the truth
is continuous and equals the corrected pose at every match. Leaving each match out and
predicting it from its neighbours (twice the real gap) gives 4 cm / 1.2 deg median error, against
6 cm / 2.8 deg when carrying from the nearest match alone; the raw odometry's yaw stutters while
the robot turns in place, and a few percent of those predictions stay off by more than 5 deg.
"""

from __future__ import annotations

import jax
import numpy as np

from mfcl_jax import se2

__all__ = ["bag_ground_truth", "truth_at_scans", "carry"]

_BUCKET = 1024  # rows; one compiled shape per bucket, whatever the window's length


@jax.jit
def _blend(odo_a, odo_b, odo, true_a, true_b, w):
    pa = se2.compose(true_a, se2.between(odo_a, odo))
    pb = se2.compose(true_b, se2.between(odo_b, odo))
    return se2.compose(pa, se2.between(pa, pb) * w[:, None])


def _padded_blend(odo_a, odo_b, odo, true_a, true_b, w) -> np.ndarray:
    k = len(odo)
    cap = _BUCKET * max(1, -(-k // _BUCKET))

    def pad(a, width=3):
        a = np.asarray(a, np.float32).reshape(k, -1)
        return np.concatenate([a, np.zeros((cap - k, width), np.float32)]).reshape(cap, width)

    args = [pad(a) for a in (odo_a, odo_b, odo, true_a, true_b)] + [pad(w, 1)[:, 0]]
    return np.asarray(_blend(*args), np.float64)[:k]


def carry(odo_from, odo_to, true_from) -> np.ndarray:
    """``true_from odo_from^-1 odo_to`` row by row: a true pose moved by the odometry's motion.

    Args:
        odo_from, odo_to, true_from: ``(K, 3)`` poses.

    Returns:
        ``(K, 3)`` float64 poses.
    """
    return _padded_blend(odo_from, odo_from, odo_to, true_from, true_from, np.zeros(len(odo_to)))


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
    """True poses at bag scans from matched corrected poses (module doc).

    Args:
        bag: ``io.BagScans``.
        sel: ``(K,)`` indices of the bag scans that need a true pose.
        bag_index: ``(M,)`` increasing indices (M >= 2) of bag scans with a trusted corrected
            pose.
        log_poses: ``(M, 3)`` those corrected poses.

    Returns:
        ``(poses (K, 3), gap (K,))``: the true poses and the time (s) from each scan to the
        nearest matched scan.
    """
    sel = np.asarray(sel, int)
    mt = bag.times[bag_index]
    t = bag.times[sel]
    b = np.clip(np.searchsorted(mt, t, "right"), 1, len(mt) - 1)
    a = b - 1
    w = np.clip((t - mt[a]) / (mt[b] - mt[a]), 0.0, 1.0)
    odo, true = bag.odometry, np.asarray(log_poses)
    poses = _padded_blend(odo[bag_index[a]], odo[bag_index[b]], odo[sel], true[a], true[b], w)
    return poses, np.minimum(np.abs(t - mt[a]), np.abs(mt[b] - t))
