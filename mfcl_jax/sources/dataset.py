"""Dataset folders (ARCHITECTURE.md): a floor plan, odometry, one PCD scan per odometry line.

```
folder/
  floorplan.geojson | floorplan.ifc | floorplan.yaml (+ its image)
  odometry.tum          sensor pose in L, one line per scan
  scans/<t>.pcd         points in the sensor frame; <t> is the odometry line's time string
  groundtruth.tum       optional: sensor pose in B at the same times (scoring only)
```
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.io.atomic import check_output, publish_mode
from mfcl_jax.io.errors import DataError
from mfcl_jax.io.pcd import read_pcd, write_pcd
from mfcl_jax.io.tum import format_time, read_tum, write_tum

__all__ = ["Dataset", "load_dataset", "write_dataset"]

FLOORPLAN_NAMES = ("floorplan.geojson", "floorplan.json", "floorplan.ifc", "floorplan.yaml")


@dataclass(frozen=True, eq=False)
class Dataset:
    """A loaded dataset folder.

    Attributes:
        folder: where it was read from.
        floorplan: the building model (frame B).
        times: ``(N,)`` scan times (s).
        time_strings: the times as written (the scan file names).
        scans: ``N`` arrays ``(n_i, 2)`` (``(n_i, 3)`` when loaded with ``xyz``), points in
            the sensor frame.
        odometry: ``(N, 3)`` sensor poses in L (the SENSOR pose, not the robot base: no
            mounting offset is applied to a dataset's odometry).
        groundtruth: ``(N, 3)`` sensor poses in B (the plan's file frame), or None.
        dropped: ``(N,)`` number of non-finite points dropped from each scan.
    """

    folder: Path
    floorplan: Floorplan
    times: np.ndarray
    time_strings: tuple[str, ...]
    scans: list[np.ndarray]
    odometry: np.ndarray
    groundtruth: np.ndarray | None = None
    dropped: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

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

    Args:
        folder: the dataset folder.
        storey: IFC storey (when the floor plan is an IFC file).
        floorplan: use this floor plan instead of the folder's (the folder then needs none).
        xyz: keep z: scans ``(n_i, 3)``.
        free_thresh, occupied_thresh: override a ROS-map floor plan's thresholds.

    Raises:
        DataError: missing pieces, a scan without a matching odometry line (or the reverse),
            ground truth at other times; FloorplanError for a bad floor plan.
    """
    from mfcl_jax.floorplan.load import load_floorplan

    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(f"{folder}: dataset folder not found")
    if floorplan is None:
        plans = [folder / n for n in FLOORPLAN_NAMES if (folder / n).is_file()]
        if len(plans) != 1:
            found = [p.name for p in plans] or "none"
            raise DataError(f"{folder}: need exactly one of {FLOORPLAN_NAMES}, found {found}")
        fp = load_floorplan(
            plans[0], storey=storey, free_thresh=free_thresh, occupied_thresh=occupied_thresh
        )
    else:
        fp = floorplan
    times, odom, strs = read_tum(folder / "odometry.tum", with_strings=True)
    if len(times) == 0:
        raise DataError(f"{folder / 'odometry.tum'}: no poses")
    scan_dir = folder / "scans"
    if not scan_dir.is_dir():
        raise DataError(f"{scan_dir}: scans folder not found")
    files = {p.stem: p for p in scan_dir.glob("*.pcd")}
    index = {s: i for i, s in enumerate(strs)}
    for stem, p in sorted(files.items()):
        if stem not in index:
            near = [s for s in strs if _same_number(s, stem)]
            hint = f" (odometry has {near[0]!r}: the strings must match)" if near else ""
            raise DataError(f"{p}: scan time {stem!r} has no odometry line{hint}")
    missing = [s for s in strs if s not in files]
    if missing:
        raise DataError(
            f"{folder / 'odometry.tum'}: {len(missing)} odometry lines have no scan in "
            f"{scan_dir}, first t={missing[0]}"
        )
    scans, dropped = [], []
    for s in strs:
        pts, nd = read_pcd(files[s], return_dropped=True, xyz=xyz)
        scans.append(pts)
        dropped.append(nd)
    gt = None
    gt_path = folder / "groundtruth.tum"
    if gt_path.is_file():
        gt_t, gt, gt_s = read_tum(gt_path, with_strings=True)
        if gt_s != strs:
            raise DataError(
                f"{gt_path}: ground truth must have one line per odometry line at the same times "
                f"({len(gt_s)} lines vs {len(strs)})"
            )
    return Dataset(folder, fp, times, tuple(strs), scans, odom, gt, np.asarray(dropped, int))


def _same_number(a: str, b: str) -> bool:
    try:
        return float(a) == float(b)
    except ValueError:
        return False


def write_dataset(
    folder, floorplan, times, scans, odometry, groundtruth=None, overwrite: bool = False
) -> Path:
    """Writes a dataset folder atomically: everything goes to a temporary sibling folder that
    is renamed into place only when complete.

    Args:
        folder: target folder.
        floorplan: a ``Floorplan`` (written as GeoJSON) or a floor-plan file to copy
            (``.geojson``, ``.ifc``, or ``.yaml`` with its image).
        times: ``(N,)`` increasing scan times.
        scans: ``N`` arrays ``(n_i, 2)`` or ``(n_i, 3)``.
        odometry: ``(N, 3)`` poses in L.
        groundtruth: optional ``(N, 3)`` poses in B.
        overwrite: replace an existing folder.

    Raises:
        DataError: inconsistent lengths, the folder exists and ``overwrite`` is False, or
            it cannot be written (``atomic.check_output``; nothing is left behind).
    """
    from mfcl_jax.floorplan.geojson import save_geojson

    folder = Path(folder)
    times = np.asarray(times, float).reshape(-1)
    if len(scans) != len(times) or len(np.asarray(odometry).reshape(-1, 3)) != len(times):
        raise DataError(
            f"{folder}: {len(times)} times, {len(scans)} scans and "
            f"{len(np.asarray(odometry).reshape(-1, 3))} odometry poses must agree"
        )
    if folder.exists() and not overwrite:
        raise DataError(f"{folder}: already exists (pass overwrite=True to replace it)")
    check_output(folder, folder=True)
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}.tmp-"))
    except OSError as e:
        raise DataError(f"{folder}: cannot create the dataset folder ({e.strerror})") from None
    try:
        publish_mode(tmp, folder=True)
        if isinstance(floorplan, Floorplan):
            save_geojson(floorplan, tmp / "floorplan.geojson")
        else:
            _copy_floorplan(Path(floorplan), tmp)
        strs = [format_time(t) for t in times]
        if len(set(strs)) != len(strs):
            raise DataError(f"{folder}: scan times are not distinct at 1 ns")
        write_tum(tmp / "odometry.tum", times, odometry, strs)
        if groundtruth is not None:
            write_tum(tmp / "groundtruth.tum", times, groundtruth, strs)
        (tmp / "scans").mkdir()
        for s, pts in zip(strs, scans, strict=True):
            write_pcd(tmp / "scans" / f"{s}.pcd", pts)
        if folder.exists():
            old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
            os.replace(folder, old)
            os.replace(tmp, folder)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, folder)
    except OSError as e:
        shutil.rmtree(tmp, ignore_errors=True)
        raise DataError(f"{folder}: cannot write the dataset ({e.strerror or e})") from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _copy_floorplan(src: Path, dst_dir: Path) -> None:
    suffix = src.suffix.lower()
    if not src.is_file():
        raise DataError(f"{src}: floor-plan file not found")
    if suffix in (".geojson", ".json", ".ifc"):
        shutil.copyfile(src, dst_dir / f"floorplan{'.geojson' if suffix == '.json' else suffix}")
    elif suffix in (".yaml", ".yml"):
        data = yaml.safe_load(src.read_text())
        img = src.parent / data["image"]
        shutil.copyfile(img, dst_dir / f"floorplan{img.suffix}")
        data["image"] = f"floorplan{img.suffix}"
        (dst_dir / "floorplan.yaml").write_text(yaml.safe_dump(data))
    else:
        raise DataError(f"{src}: unknown floor-plan format {suffix!r}")
