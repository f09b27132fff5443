"""Real laser logs as benchmark recordings: windows of travel, each with a held-out map.

Four corrected CARMEN logs (``LOGS``; ``shared/data/laser/<name>-corrected.log.gz``: real
180 deg front-laser scans with SLAM-corrected poses) and the raw Intel ROS bag (real scans,
real drifting ``/odom``).

A window is a stretch of ``length_m`` metres of travel along the corrected poses
(``logwindows.plan_windows``): ``n_windows`` windows are spread evenly over the log and never
share a scan; a request the log cannot hold is a ``ValueError`` that names the log, its length
and the request, raised before any map is built.

Each window gets its own floor plan: an occupancy map of the same log built from every scan
EXCEPT the window's and those within ``logwindows.EXCLUDE_MARGIN_M`` (2 m) of travel before or
after it (the neighbours of the window's end scans see nearly the same view; a prior map is made
at another time). Places the robot saw on other passes stay in the map, as they would in a real
prior map.
The map is written as a ROS map and read back by ``load_rosmap`` (its room segmentation gives
the rooms and doors); see ``sources.heldout`` for the cache. A place that only the window saw
is missing from its map: ``meta["map_coverage"]`` is the fraction of the window's true positions
that lie on free cells of the map (near 1 where the log passes the window's places again, as
Intel, Freiburg 101 and Seattle mostly do; low for the Orebro log, a single pass).

CARMEN windows: the scans of the window (lines whose time goes backwards dropped), ground truth
the corrected poses, odometry derived from them with seeded drift (``sim.trajectory.odometry``:
``drift_xy`` of each increment's length per axis, ``drift_yaw_deg`` per metre), starting at the
identity, so the hidden anchor is the first true pose. The Orebro log has no clock: its lines
are numbered ``UNTIMED_PERIOD_S`` apart.

Bag windows: the same windows of the corrected Intel log, mapped to the bag's clock
(``bagtruth``); every bag scan in that time span with the bag's own odometry, re-based to start
at the identity; ground truth from the matched corrected poses.
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np

from mfcl_jax.sim.trajectory import odometry
from mfcl_jax.sources.bagtruth import bag_ground_truth, carry, truth_at_scans
from mfcl_jax.sources.data import data_dir
from mfcl_jax.sources.heldout import default_cache_dir, file_digest, held_out_map
from mfcl_jax.sources.logwindows import plan_windows
from mfcl_jax.sources.recording import GroundTruth, Recording
from mfcl_jax.sources.sequence import ScanSequence

__all__ = [
    "LOGS",
    "log_path",
    "read_log",
    "log_recordings",
    "bag_recordings",
    "full_map",
]

LOGS: tuple[str, ...] = ("intel", "freiburg-101", "orebro", "seattle")
DATA = data_dir()
UNTIMED_PERIOD_S = 1.0
BAG_AGREE = 0.95  # a bag <-> log match is trusted when this fraction of points coincide
_BUCKET = 256  # odometry rows; one compiled shape per bucket, whatever the window's length
_odometry = jax.jit(odometry)


def _travelled(poses) -> np.ndarray:
    """Cumulative planar distance along ``poses (T, 3)``, from 0."""
    xy = np.asarray(poses, np.float64)[:, :2]
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


def log_path(name: str) -> Path:
    """The corrected CARMEN log of ``name`` (one of ``LOGS``)."""
    if name not in LOGS:
        raise ValueError(f"unknown log {name!r}; choose one of {', '.join(LOGS)}")
    return DATA / "laser" / f"{name}-corrected.log.gz"


def read_log(name: str):
    """``io.read_carmen`` of a log of ``LOGS`` (numbering the lines of a log without clock)."""
    from mfcl_jax.io import read_carmen

    return read_carmen(log_path(name), untimed_period=UNTIMED_PERIOD_S)


def _cache(cache_dir) -> Path:
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    if folder.resolve().is_relative_to(DATA):
        raise ValueError(f"cache_dir {folder} lies in the read-only data folder {DATA}")
    return folder


def _check(name, map_res, drift_xy=0.0, drift_yaw_deg=0.0):
    if not (np.isfinite(map_res) and map_res > 0):
        raise ValueError(f"log {name!r}: map_res must be > 0 (m), got {map_res!r}")
    for field, v in (("drift_xy", drift_xy), ("drift_yaw_deg", drift_yaw_deg)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"log {name!r}: {field} must be >= 0, got {v!r}")


def _time_ok(times) -> np.ndarray:
    """Lines whose time is later than every earlier line's (the ones ``ScanSequence`` takes)."""
    t = np.asarray(times)
    return np.concatenate([[True], t[1:] > np.maximum.accumulate(t)[:-1]])


def _maps(name, log, windows, map_res, cache_dir):
    """The held-out map of each window (shared by the log and the bag windows of Intel)."""
    data_id = f"{name}:{file_digest(log_path(name))[:16]}"
    folder = _cache(cache_dir)
    everything = np.arange(len(log))
    for w in windows:
        h0, h1 = w.held_out
        use = everything[(everything < h0) | (everything > h1)]
        yield held_out_map(
            log.poses, log.scans, use, map_res, data_id, f"{name}_x{h0}-{h1}", folder
        )


def full_map(name: str, map_res: float = 0.10, cache_dir=None):
    """The map of a whole log (every scan), for pictures; a ``heldout.HeldOutMap``."""
    _check(name, map_res)
    log = read_log(name)
    data_id = f"{name}:{file_digest(log_path(name))[:16]}"
    return held_out_map(
        log.poses,
        log.scans,
        np.arange(len(log)),
        map_res,
        data_id,
        f"{name}_all",
        _cache(cache_dir),
    )


def _drifting_odometry(true, key, drift_xy, drift_yaw_deg) -> np.ndarray:
    """``sim.trajectory.odometry`` from the first true pose (so it starts at the identity).

    The poses are padded with copies of the last one (zero increments, no drift) to a bucket
    of rows, so windows of any length share one compiled shape; drifts are traced."""
    n = len(true)
    cap = _BUCKET * max(1, -(-n // _BUCKET))
    y = np.concatenate([true, np.repeat(true[-1:], cap - n, 0)]).astype(np.float32)
    noise = jax.random.normal(key, (cap, 3))
    x = _odometry(y, y[0], noise, np.float32(drift_xy), np.float32(np.deg2rad(drift_yaw_deg)))
    return np.asarray(x, np.float64)[:n]


def _meta(family, seed, w, length_m, map_res, hm, truth_xy, **extra) -> dict:
    return {
        "family": family,
        "seed": seed,
        "trajectory": f"w{w.number}",
        "length_m": float(length_m),
        "map_res": float(map_res),
        "start_m": round(w.start_m, 2),
        "travel_m": round(w.travel_m, 2),
        "log_scans": (w.first, w.last),
        "held_out": w.held_out,
        "map_file": str(hm.yaml_path),
        "map_coverage": round(hm.coverage(truth_xy), 3),
        **extra,
    }


def log_recordings(
    name: str,
    n_windows: int,
    length_m: float = 60.0,
    map_res: float = 0.10,
    drift_xy: float = 0.01,
    drift_yaw_deg: float = 0.5,
    seed: int = 0,
    cache_dir=None,
) -> list[Recording]:
    """Windows of a corrected CARMEN log, each with its held-out map (module doc).

    Args:
        name: one of ``LOGS``.
        n_windows: how many windows.
        length_m: travel per window (m).
        map_res: the held-out maps' cell size (m).
        drift_xy: odometry translation drift, fraction of each increment's length per axis.
        drift_yaw_deg: odometry yaw drift (deg per metre).
        seed: seed of the odometry drift (window ``i`` folds ``i`` into it).
        cache_dir: map cache folder (default ``heldout.default_cache_dir()``).

    Returns:
        ``n_windows`` recordings named ``log-<name>/wNN``; ``meta`` also holds ``start_m``,
        ``travel_m``, the window's scan range ``log_scans``, the ``held_out`` scan range, the
        ``map_file`` (``heldout.recorded_scans(map_file)`` lists the scans it was built
        from), ``map_coverage`` and ``clock``.

    Raises:
        ValueError: unknown log, bad arguments, or a log too short for the request.
    """
    _check(name, map_res, drift_xy, drift_yaw_deg)
    log = read_log(name)
    windows = plan_windows(_travelled(log.poses), n_windows, length_m, name)
    ok = _time_ok(log.times)
    src = log_path(name).name
    recs = []
    for w, hm in zip(windows, _maps(name, log, windows, map_res, cache_dir), strict=True):
        idx = w.scans[ok[w.scans]]
        true = log.poses[idx]
        key = jax.random.fold_in(jax.random.PRNGKey(seed), w.number)
        odo = _drifting_odometry(true, key, drift_xy, drift_yaw_deg)
        where = f"{src} w{w.number:02d}"
        recs.append(
            Recording(
                name=f"log-{name}/w{w.number:02d}",
                floorplan=hm.floorplan,
                seq=ScanSequence(log.times[idx], [log.scans[i] for i in idx], odo, where),
                truth=GroundTruth(log.times[idx], true, where),
                meta=_meta(
                    "log:" + name,
                    seed,
                    w,
                    length_m,
                    map_res,
                    hm,
                    true[:, :2],
                    clock="log" if log.timed else f"line number x {UNTIMED_PERIOD_S:g} s",
                ),
            )
        )
    return recs


def bag_recordings(
    n_windows: int, length_m: float = 60.0, map_res: float = 0.10, cache_dir=None
) -> list[Recording]:
    """Windows of the raw Intel bag: real scans and odometry, held-out maps (module doc).

    The windows are those of ``log_recordings("intel", n_windows, length_m)`` (same scans left
    out of the same maps, shared through the cache).

    Returns:
        ``n_windows`` recordings named ``bag-intel/wNN``; ``meta`` as for the log windows plus
        ``time_offset_s`` (bag clock minus log clock), ``truth_matches`` (corrected-log scans
        matched to bag scans with more than ``BAG_AGREE`` of their points identical) and
        ``truth_gap_s`` (the longest time over which a true pose was carried by the bag
        odometry).
    """
    from mfcl_jax.io import read_bag

    _check("intel", map_res)
    log = read_log("intel")
    windows = plan_windows(_travelled(log.poses), n_windows, length_m, "intel")
    bag_file = DATA / "laser" / "intel.orig.bag"
    bag = read_bag(bag_file, "/scan", "/odom")
    off, bi, li, agree = bag_ground_truth(bag, log)
    good = agree > BAG_AGREE
    bi, order = np.unique(bi[good], return_index=True)
    li = li[good][order]
    ok = _time_ok(log.times)
    recs = []
    for w, hm in zip(windows, _maps("intel", log, windows, map_res, cache_dir), strict=True):
        idx = w.scans[ok[w.scans]]
        t_lo, t_hi = log.times[idx[0]] + off, log.times[idx[-1]] + off
        sel = np.flatnonzero((bag.times >= t_lo) & (bag.times <= t_hi))
        true, gap = truth_at_scans(bag, sel, bi, log.poses[li])
        # Re-based to start at the identity, like the log windows.
        odo = carry(
            np.broadcast_to(bag.odometry[sel[0]], (len(sel), 3)),
            bag.odometry[sel],
            np.zeros((len(sel), 3)),
        )
        where = f"{bag_file.name} w{w.number:02d}"
        recs.append(
            Recording(
                name=f"bag-intel/w{w.number:02d}",
                floorplan=hm.floorplan,
                seq=ScanSequence(bag.times[sel], [bag.scans[i] for i in sel], odo, where),
                truth=GroundTruth(bag.times[sel], true, where),
                meta=_meta(
                    "bag:intel",
                    0,
                    w,
                    length_m,
                    map_res,
                    hm,
                    true[:, :2],
                    time_offset_s=round(float(off), 4),
                    truth_matches=len(bi),
                    truth_gap_s=round(float(gap.max()), 2),
                ),
            )
        )
    return recs
