"""Dataset folders (ARCHITECTURE.md): a floor plan, odometry at any rate, PCD scans.

```
folder/
  floorplan.geojson | floorplan.ifc | floorplan.yaml (+ its image)
  odometry.tum          sensor pose in L, at any rate, lines in time order
  scans/<t>.pcd         points in the sensor frame (metres); <t> the scan's time (s)
  groundtruth.tum       optional: sensor pose in B at any rate (scoring only)
```

Times are compared as numbers (``scans/1000.5.pcd`` and an odometry line ``1000.500000`` are
one instant); the odometry and the ground truth are interpolated to each scan's time
(``io.timesync``). ``write_dataset`` writes one odometry line per scan, named alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.io.errors import DataError
from mfcl_jax.io.pcd import read_pcd
from mfcl_jax.io.timesync import odometry_at, poses_at
from mfcl_jax.io.tum import read_tum
from mfcl_jax.io.units import check_metres, check_plan_scale, check_some_points

__all__ = ["Dataset", "load_dataset", "FLOORPLAN_NAMES", "DATASET_PARTS"]

FLOORPLAN_NAMES = ("floorplan.geojson", "floorplan.json", "floorplan.ifc", "floorplan.yaml")
# what a dataset folder holds besides its floor plan (floorplan.* and a ROS map's image)
DATASET_PARTS = ("odometry.tum", "groundtruth.tum", "scans")


@dataclass(frozen=True, eq=False)
class Dataset:
    """A loaded dataset folder.

    Attributes:
        folder: where it was read from.
        floorplan: the building model (frame B).
        times: ``(N,)`` increasing scan times (s), of the scans within the odometry's span.
        time_strings: the times as written (the scan file names without ``.pcd``).
        scans: ``N`` arrays ``(n_i, 2)`` (``(n_i, 3)`` when loaded with ``xyz``), points in
            the sensor frame.
        odometry: ``(N, 3)`` sensor poses in L at the scan times (the SENSOR pose, not the
            robot base: no mounting offset is applied to a dataset's odometry).
        groundtruth: ``(N, 3)`` sensor poses in B (the plan's file frame) at the scan times,
            or None.
        dropped: ``(N,)`` number of non-finite points dropped from each scan.
        outside: scan files left out because they lie outside the odometry's time span.
    """

    folder: Path
    floorplan: Floorplan
    times: np.ndarray
    time_strings: tuple[str, ...]
    scans: list[np.ndarray]
    odometry: np.ndarray
    groundtruth: np.ndarray | None = None
    dropped: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    outside: int = 0

    def __len__(self) -> int:
        return len(self.times)


def load_dataset(
    folder,
    storey=None,
    floorplan: Floorplan | None = None,
    xyz: bool = False,
    free_thresh: float | None = None,
    occupied_thresh: float | None = None,
) -> Dataset:
    """Loads a dataset folder.

    Scans are matched to the odometry by time as numbers (``io.timesync``): the odometry may
    come at any rate and with stamps written differently from the scan names; it is
    interpolated in SE(2) to each scan's stamp. Scans more than ``TIME_TOL_S`` (1 ms) outside
    the odometry's time span are left out with a ``DataWarning`` (count and span). The ground
    truth, when present, is interpolated the same way and must cover every scan kept.

    Args:
        folder: the dataset folder.
        storey: IFC storey (when the floor plan is an IFC file).
        floorplan: use this floor plan instead of the folder's (the folder then needs none).
        xyz: keep z: scans ``(n_i, 3)``.
        free_thresh, occupied_thresh: override a ROS-map floor plan's thresholds.

    Raises:
        DataError: missing pieces, a scan file name that is not a time, two scans at one time,
            odometry lines out of time order, no scan within the odometry's span, ground truth
            that does not cover the scans, scans in millimetres or a plan and scans whose
            scales disagree (``io.units``); FloorplanError for a bad floor plan.

    Warns:
        DataWarning: scans outside the odometry's span, non-unit quaternions.
    """
    from mfcl_jax.floorplan.load import load_building

    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(f"{folder}: dataset folder not found")
    plan_name = f"the floor plan given ({getattr(floorplan, 'name', '?')})"
    if floorplan is None:
        plans = [folder / n for n in FLOORPLAN_NAMES if (folder / n).is_file()]
        if len(plans) != 1:
            found = [p.name for p in plans] or "none"
            raise DataError(f"{folder}: need exactly one of {FLOORPLAN_NAMES}, found {found}")
        fp = load_building(
            plans[0], storey=storey, free_thresh=free_thresh, occupied_thresh=occupied_thresh
        )
        plan_name = str(plans[0])
    else:
        fp = floorplan
    odo_path = folder / "odometry.tum"
    o_t, o_p = read_tum(odo_path)
    if len(o_t) == 0:
        raise DataError(f"{odo_path}: no poses")
    files, st = _scan_files(folder / "scans")
    inside, odom = odometry_at(o_t, o_p, st, str(odo_path))
    keep = np.flatnonzero(inside)
    scans, dropped = [], []
    for i in keep:
        pts, nd = read_pcd(files[i], return_dropped=True, xyz=xyz)
        scans.append(pts)
        dropped.append(nd)
    check_some_points(scans, str(folder))
    median_range = check_metres(scans, [str(files[i]) for i in keep], str(folder))
    check_plan_scale(fp.bounds, median_range, plan_name, str(folder / "scans"))
    gt = None
    gt_path = folder / "groundtruth.tum"
    if gt_path.is_file():
        gt_t, gt_p = read_tum(gt_path)
        if len(gt_t) == 0:
            raise DataError(f"{gt_path}: no poses")
        gt = poses_at(gt_t, gt_p, st[keep], str(gt_path))
    return Dataset(
        folder,
        fp,
        st[keep],
        tuple(files[i].stem for i in keep),
        scans,
        odom,
        gt,
        np.asarray(dropped, int),
        outside=len(st) - len(keep),
    )


def _scan_files(scan_dir: Path) -> tuple[list[Path], np.ndarray]:
    """The scan files ``(N,)`` and their times ``(N,)`` (s, from the names), in time order.

    Raises:
        DataError: no folder or no scan, a name that is not a finite number, two names of
            the same time (``1.5.pcd`` and ``1.50.pcd``).
    """
    if not scan_dir.is_dir():
        raise DataError(f"{scan_dir}: scans folder not found")
    files = sorted(scan_dir.glob("*.pcd"))
    if not files:
        raise DataError(f"{scan_dir}: no scans (<t>.pcd files)")
    times = []
    for p in files:
        try:
            t = float(p.stem)
        except ValueError:
            t = math.nan
        if not math.isfinite(t):
            raise DataError(
                f"{p}: a scan file is named by its time in seconds (e.g. 1000.5.pcd), "
                f"got {p.stem!r}"
            )
        times.append(t)
    order = np.argsort(times, kind="stable")
    files, times = [files[i] for i in order], np.asarray(times, np.float64)[order]
    same = np.flatnonzero(np.diff(times) <= 0)
    if len(same):
        a, b = files[same[0]], files[same[0] + 1]
        raise DataError(f"{b}: scan time t={float(times[same[0]])!r} is also the time of {a.name}")
    return files, times
