"""Units of scans: metres expected; millimetres, or a plan and scans of different scales,
refused with the evidence.

Rules (on the first ``N_FIRST`` (50) non-empty scans: enough for a robust median, read before
any work):

1. Each scan's median range (distance of its finite points from the sensor) is taken, then
   the median over those scans. Above ``MM_MEDIAN_RANGE`` (200) the scans are taken as
   millimetres and refused: indoors a LiDAR's median range is 1-20 m (a 3-D LiDAR outdoors
   rarely above 50 m), while the same scans in millimetres give 1,000-20,000.
2. With a floor plan: ``ratio`` = the plan's larger side / that median range. A building
   is 3 to 500 times the median range its scans see; a plan in millimetres read as metres
   gives 3,000 and more. Above ``MAX_PLAN_RATIO`` (2,000), or below ``MIN_PLAN_RATIO``
   (0.05: scans seeing 20 times past the whole plan), the two are refused in one message
   naming both. Scans with a median range under 1 mm carry no scale and are not judged.

Nothing is converted: a guessed unit is never applied silently (as for GeoJSON plans,
``floorplan.geojson_units``).
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.io.errors import DataError

__all__ = [
    "N_FIRST",
    "MM_MEDIAN_RANGE",
    "MAX_PLAN_RATIO",
    "MIN_PLAN_RATIO",
    "median_ranges",
    "check_metres",
    "check_some_points",
    "check_plan_scale",
]

N_FIRST = 50
MM_MEDIAN_RANGE = 200.0
MAX_PLAN_RATIO = 2000.0
MIN_PLAN_RATIO = 0.05


def median_ranges(scans, limit: int = N_FIRST) -> tuple[np.ndarray, np.ndarray]:
    """Median ranges of the first ``limit`` scans that have finite points.

    Args:
        scans: arrays ``(n_i, d)`` of points in the sensor frame (``d`` = 2 or 3), or
            ``(n_i, 1)`` raw ranges.
        limit: how many non-empty scans to look at.

    Returns:
        ``(index (k,), median (k,))``: which scans were used and their median ranges.
    """
    idx, med = [], []
    for i, s in enumerate(scans):
        p = np.asarray(s, np.float64)
        if p.size == 0:
            continue
        p = p.reshape(len(p), -1)
        r = np.linalg.norm(p[np.all(np.isfinite(p), 1)], axis=1)
        if len(r):
            idx.append(i)
            med.append(float(np.median(r)))
            if len(idx) == limit:
                break
    return np.asarray(idx, int), np.asarray(med, np.float64)


def check_some_points(scans, where: str) -> None:
    """Refuses a recording whose every scan is empty (no finite point): nothing could ever be
    registered, so no window could be decided (``DataError`` saying so)."""
    if len(scans) and not len(median_ranges(scans, limit=1)[0]):
        raise DataError(
            f"{where}: every one of its {len(scans)} scans is empty (0 finite points): the "
            "LiDAR saw nothing, or its points were dropped on the way (a wrong topic, field or "
            "range filter); nothing can be localized without points"
        )


def check_metres(scans, names, where: str) -> float:
    """Refuses scans that look like millimetres (module rule 1).

    Args:
        scans: arrays of points (``median_ranges``).
        names: a name per scan for messages (its file, or bag topic and stamp).
        where: the input (dataset folder, bag), for messages.

    Returns:
        The median range of the first scans (NaN without a finite point).

    Raises:
        DataError: naming the first scan judged, its median range, the overall median range
            and saying the localizer expects metres.
    """
    idx, med = median_ranges(scans)
    if not len(med):
        return float("nan")
    overall = float(np.median(med))
    if overall > MM_MEDIAN_RANGE:
        raise DataError(
            f"{names[idx[0]]}: scan ranges look like millimetres, not metres: median range "
            f"{overall:.0f} over the first {len(med)} scans of {where} ({med[0]:.0f} in this "
            f"one), above {MM_MEDIAN_RANGE:g} (scans in metres see a median 1 to 20 m "
            "indoors); the localizer expects scans in metres: convert them (divide by 1000)"
        )
    return overall


def check_plan_scale(bounds, median_range: float, plan: str, where: str) -> None:
    """Refuses a floor plan and scans whose scales disagree (module rule 2).

    Args:
        bounds: the plan's ``(xmin, ymin, xmax, ymax)`` (its file's units, taken as metres).
        median_range: ``check_metres``' median scan range (m).
        plan: the plan's file or name, for messages.
        where: the scans' input, for messages.

    Raises:
        DataError: one message naming the plan, its extent, the scans and their median range.
    """
    if not (np.isfinite(median_range) and median_range >= 1e-3):
        return
    x0, y0, x1, y1 = (float(v) for v in bounds)
    extent = max(x1 - x0, y1 - y0)
    ratio = extent / median_range
    if MIN_PLAN_RATIO <= ratio <= MAX_PLAN_RATIO:
        return
    hint = (
        "a plan in millimetres read as metres is 1000 times too large"
        if ratio > MAX_PLAN_RATIO
        else "the scans see far past the whole plan"
    )
    raise DataError(
        f"{plan}: the floor plan and the scans of {where} disagree in scale: the plan is "
        f"{x1 - x0:.4g} x {y1 - y0:.4g} units, the scans' median range is {median_range:.4g} "
        f"units, a ratio of {ratio:.4g} (a building is 3 to 500 times the median range of "
        f"its scans; refused outside {MIN_PLAN_RATIO:g} to {MAX_PLAN_RATIO:g}: {hint}); the "
        "localizer expects both in metres"
    )
