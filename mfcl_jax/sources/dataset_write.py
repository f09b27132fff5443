"""Writing a dataset folder (``write_dataset``, the layout ``sources.dataset`` reads), all or
nothing: a temporary sibling folder renamed into place when complete; only a folder that is a
dataset is ever replaced."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import yaml

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.io.atomic import check_output, publish_mode
from mfcl_jax.io.errors import DataError
from mfcl_jax.io.pcd import write_pcd
from mfcl_jax.io.tum import format_time, write_tum
from mfcl_jax.sources.dataset import DATASET_PARTS

__all__ = ["write_dataset"]


def write_dataset(
    folder,
    floorplan,
    times,
    scans,
    odometry,
    groundtruth=None,
    overwrite: bool = False,
    odom_times=None,
) -> Path:
    """Writes a dataset folder atomically: everything goes to a temporary sibling folder that
    is renamed into place only when complete.

    Args:
        folder: target folder.
        floorplan: a ``Floorplan`` (written as GeoJSON) or a floor-plan file to copy
            (``.geojson``, ``.ifc``, or ``.yaml`` with its image).
        times: ``(N,)`` increasing scan times.
        scans: ``N`` arrays ``(n_i, 2)`` or ``(n_i, 3)``.
        odometry: ``(N, 3)`` poses in L (or ``(M, 3)`` at ``odom_times``).
        groundtruth: optional ``(N, 3)`` poses in B.
        overwrite: replace an existing folder.
        odom_times: optional ``(M,)`` increasing times of the odometry poses, when the
            odometry runs at its own rate (default: one pose per scan, at the scan's time).

    Raises:
        DataError: inconsistent lengths, the folder exists and ``overwrite`` is False, or
            it cannot be written (``atomic.check_output``; nothing is left behind).
    """
    from mfcl_jax.floorplan.geojson_write import save_geojson

    folder = Path(folder)
    times = np.asarray(times, float).reshape(-1)
    o_times = times if odom_times is None else np.asarray(odom_times, float).reshape(-1)
    n_odo = len(np.asarray(odometry).reshape(-1, 3))
    if len(scans) != len(times) or n_odo != len(o_times):
        raise DataError(
            f"{folder}: {len(times)} times, {len(scans)} scans, {len(o_times)} odometry times "
            f"and {n_odo} odometry poses must agree"
        )
    if folder.exists() and not overwrite:
        raise DataError(f"{folder}: already exists (pass overwrite=True to replace it)")
    if folder.exists():
        _check_replaceable(folder)
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
        if odom_times is None:
            write_tum(tmp / "odometry.tum", times, odometry, strs)
        else:
            write_tum(tmp / "odometry.tum", o_times, odometry, [format_time(t) for t in o_times])
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


def _check_replaceable(folder: Path) -> None:
    """Only a dataset folder is replaced: a folder holding ``odometry.tum`` or ``scans/`` and
    nothing but a dataset's files (``DataError`` naming what else it holds)."""
    if not folder.is_dir():
        raise DataError(
            f"{folder}: exists and is not a folder; overwrite replaces a dataset folder"
        )
    names = {p.name for p in folder.iterdir()}
    if not names & {"odometry.tum", "scans"}:
        raise DataError(
            f"{folder}: overwrite replaces a dataset folder, and this one holds no odometry.tum "
            f"and no scans/ ({len(names)} entries, e.g. {sorted(names)[:3]}); it was left as it is"
        )
    other = sorted(n for n in names - set(DATASET_PARTS) if not n.startswith("floorplan."))
    if other:
        raise DataError(
            f"{folder}: overwrite replaces a dataset folder, and this one also holds {other[:3]}"
            f"{' ...' if len(other) > 3 else ''}, which a dataset does not; it was left as it is"
        )


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
