"""What ``mfcl localize`` reads: dataset folders, a ROS bag or a CARMEN log, with a floor plan;
2-D scans or 3-D clouds.

Odometry convention: the localizer wants SENSOR poses in L. A dataset's ``odometry.tum`` is
already the sensor pose (no planar mounting is applied to it). A bag's or CARMEN log's
odometry is the robot base's: ``--lidar-offset x,y,yaw_deg`` or ``--lidar-mount
x,y,z,roll,pitch,yaw`` (or, for bags, ``--tf-static``: the ``/tf_static`` chain from
``--base-frame`` to the scans' frame) is composed onto it, planar part only, so that the
odometry poses become sensor poses.

3-D clouds (PCD scans with z, PointCloud2 topics) are cut by a height band into planar scans
(``sources.planar``: 2-D or 3-D decided by the z extent, ``--input-dim`` overrides). The part
of the mounting the planar odometry cannot hold (height, roll, pitch; from ``--lidar-mount``
or ``/tf_static``) levels the clouds before the cut.

Anchors and poses in the decision log are in the floor plan's file frame
(``robot.records.record``). The flags themselves: ``mfcl_jax.cli.flags``.
"""

from __future__ import annotations

import math
from pathlib import Path

__all__ = [
    "planar_params",
    "dataset_folders",
    "input_paths",
    "check_inputs",
    "mount_flags",
    "load_input",
    "load_dataset_input",
]


def planar_params(args, mount=None):
    """``PlanarParams`` from the 3-D flags (``mount``: a ``Mount`` for the clouds).

    Raises:
        DataError: an empty or inverted band, band flags with ``--no-band``.
    """
    from mfcl_jax.io.errors import DataError
    from mfcl_jax.sources.cloud3d import BandParams
    from mfcl_jax.sources.planar import PlanarParams

    flags = {"--band-min": args.band_min, "--band-max": args.band_max}
    flags["--band-relative-to"] = args.band_relative_to
    given = [f for f, v in flags.items() if v is not None]
    if args.no_band:
        if given:
            raise DataError(f"localize: --no-band keeps every point; it takes no {given[0]}")
        return PlanarParams(dim=args.input_dim, band=None, mount=mount)
    d = BandParams()
    lo = d.z_min if args.band_min is None else args.band_min
    hi = d.z_max if args.band_max is None else args.band_max
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise DataError(
            f"localize: the band needs --band-min < --band-max, got --band-min {lo:g}, "
            f"--band-max {hi:g}"
        )
    band = BandParams(z_min=lo, z_max=hi, relative_to=args.band_relative_to or d.relative_to)
    return PlanarParams(dim=args.input_dim, band=band, mount=mount)


def dataset_folders(args) -> list[Path]:
    """The dataset folders named: each DATASET, or the dataset folders inside a single
    folder that has no ``odometry.tum`` itself (sorted by name): every sub-folder holding a
    part of a dataset (``odometry.tum``, ``groundtruth.tum`` or ``scans/``), so that one
    lacking a part is named and counted with the bad inputs, never silently left out."""
    from mfcl_jax.sources.dataset import DATASET_PARTS

    folders = list(args.dataset)
    if len(folders) == 1 and folders[0].is_dir() and not (folders[0] / "odometry.tum").exists():
        inner = sorted(p for p in folders[0].iterdir()
                       if p.is_dir() and any((p / n).exists() for n in DATASET_PARTS))  # fmt: skip
        if inner:
            return inner
    return folders


def input_paths(args, folders) -> list:
    """Every file or folder the localize run reads (an output must be none of them)."""
    from mfcl_jax.floorplan.load import floorplan_files
    from mfcl_jax.sources.dataset import FLOORPLAN_NAMES

    paths = [args.bag, args.carmen]
    plans = list(args.floorplan or [])
    for d in folders:
        paths += [d / "odometry.tum", d / "groundtruth.tum", d / "scans"]
        plans += [d / n for n in FLOORPLAN_NAMES]
    return paths + [f for p in plans for f in floorplan_files(p)]


def check_inputs(args, folders) -> None:
    """Refuses contradictory input flags (``DataError`` naming them)."""
    from mfcl_jax.io import DataError

    sources = (("DATASET", folders), ("--bag", args.bag), ("--carmen", args.carmen))
    given = [name for name, v in sources if v]
    if not given:
        raise DataError("localize: give a DATASET folder or --bag B (with --floorplan F)")
    if args.bag is not None and folders:
        raise DataError(f"localize: give either DATASET ({folders[0]}) or --bag ({args.bag})")
    if len(given) > 1:
        raise DataError(f"localize: give one input, got {' and '.join(given)}")
    if args.tf_static and args.bag is None:
        raise DataError("localize: --tf-static reads /tf_static from a bag; give --bag")
    mounts = [f for f in ("lidar_offset", "lidar_mount", "tf_static") if getattr(args, f)]
    if len(mounts) > 1:
        names = " and ".join("--" + m.replace("_", "-") for m in mounts)
        raise DataError(f"localize: give the LiDAR mounting once, got {names}")
    if folders and args.lidar_offset is not None:
        raise DataError(
            f"{folders[0]}: odometry.tum is already the sensor pose; --lidar-offset applies "
            "to --bag and --carmen"
        )
    m = args.lidar_mount
    if folders and m is not None and any((m[0], m[1], m[5])):
        raise DataError(
            f"{folders[0]}: odometry.tum is already the sensor pose; --lidar-mount's x, y, yaw "
            f"must be 0 for a dataset (got {m[0]:g}, {m[1]:g}, {math.degrees(m[5]):g} deg)"
        )
    if args.carmen is not None and m is not None and any((m[3], m[4])):
        raise DataError(
            f"{args.carmen}: a CARMEN log holds planar scans; --lidar-mount roll and pitch "
            "cannot level them (give 0)"
        )


def load_input(args, folders=()):
    """(floorplan, ScanSequence, notes) of one input: a dataset folder, a bag or a CARMEN
    log; the notes say what was dropped or applied on the way."""
    from mfcl_jax.floorplan.load import load_building
    from mfcl_jax.io import DataError

    folders = list(folders)
    check_inputs(args, folders)
    planar = planar_params(args)
    opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    fp = None
    if args.floorplan:
        fp = load_building(args.floorplan, storey=args.storey, **opts)
    if folders:
        return load_dataset_input(args, folders[0], fp, planar)
    src = args.bag if args.bag is not None else args.carmen
    if fp is None:
        kind = "bag" if args.bag is not None else "CARMEN log"
        raise DataError(f"{src}: a {kind} has no floor plan; pass --floorplan F")
    if args.bag is not None:
        seq, notes = _load_bag(args, planar)
    else:
        seq, notes = _load_carmen(args)
    _check_scale(fp, seq, " + ".join(str(p) for p in args.floorplan), src)
    return fp, seq, notes


def _check_scale(fp, seq, plan, src) -> None:
    """A plan and scans whose scales disagree are refused for bags and CARMEN logs too, as
    for dataset folders (``io.units``)."""
    from mfcl_jax.io.units import check_metres, check_plan_scale, check_some_points

    check_some_points(list(seq.scans), str(src))
    names = [f"{src} scan at t={t:.9f}" for t in seq.times]
    median = check_metres(list(seq.scans), names, str(src))
    check_plan_scale(fp.bounds, median, str(plan), str(src))


def mount_flags(args):
    """``(planar offset (x, y, yaw), Mount or None)`` of ``--lidar-offset``/``--lidar-mount``."""
    from mfcl_jax.sources.planar import mount_3d

    if args.lidar_mount is not None:
        return mount_3d(*args.lidar_mount)
    return args.lidar_offset or (0.0, 0.0, 0.0), None


def load_dataset_input(args, folder, fp, planar):
    """(floorplan, ScanSequence, notes) of a dataset folder (``fp``: a plan overriding the
    folder's, or None), its scans made planar by ``planar`` (``--lidar-mount`` levels
    them)."""
    from dataclasses import replace

    from mfcl_jax.io.pcd import pcd_fields
    from mfcl_jax.sources import load_dataset
    from mfcl_jax.sources.planar import planar_scans
    from mfcl_jax.sources.sequence import ScanSequence

    opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    # z is read whenever the scans have it (to tell 3-D from 2-D), unless told they are 2-D.
    xyz = planar.dim != 2
    if xyz:
        first = sorted((Path(folder) / "scans").glob("*.pcd"))[:1]
        xyz = planar.dim == 3 or bool(first and "z" in pcd_fields(first[0]))
    ds = load_dataset(folder, storey=args.storey, floorplan=fp, xyz=xyz, **opts)
    notes = []
    if int(ds.dropped.sum()):
        notes.append(
            f"{folder}: {int(ds.dropped.sum())} non-finite points dropped from "
            f"{int((ds.dropped > 0).sum())} scans"
        )
    planar = replace(planar, mount=mount_flags(args)[1])
    names = [str(ds.folder / "scans" / f"{s}.pcd") for s in ds.time_strings]
    scans, more = planar_scans(ds.scans, planar, names, str(folder))
    seq = ScanSequence(ds.times, scans, ds.odometry, str(ds.folder))
    return ds.floorplan, seq, notes + more


def _load_bag(args, planar):
    from dataclasses import replace

    from mfcl_jax.io import read_bag
    from mfcl_jax.io.tf_static import xyz_rpy
    from mfcl_jax.sources.planar import mount_3d, planar_scans
    from mfcl_jax.sources.sequence import ScanSequence

    offset, mount = mount_flags(args)
    bag = read_bag(
        args.bag,
        args.scan_topic,
        args.odom_topic,
        sensor_offset=offset,
        xyz=planar.dim != 2,
        base_frame=args.base_frame if args.tf_static else None,
    )
    notes = []
    if args.tf_static:
        x, y, z, roll, pitch, yaw = xyz_rpy(bag.mount)
        mount = mount_3d(x, y, z, roll, pitch, yaw)[1]
        notes.append(
            f"LiDAR mounting from /tf_static, {args.base_frame} -> {bag.frame_id}: "
            f"x={x:.3f} m, y={y:.3f} m, yaw={math.degrees(yaw):.2f} deg; z={z:.3f} m, "
            f"roll={math.degrees(roll):.2f} deg, pitch={math.degrees(pitch):.2f} deg"
        )
    for what, k in (
        ("scans repeating an earlier scan's stamp were left out", bag.duplicates),
        ("odometry messages repeating a stamp were left out", bag.odom_duplicates),
        ("scans outside the odometry's time span were left out", bag.unpaired),
        ("non-finite or zero points were dropped", bag.dropped),
    ):
        if k:
            notes.append(f"{args.bag}: {k} {what}")
    names = [f"{args.bag} {args.scan_topic} scan at t={t:.9f}" for t in bag.times]
    scans, more = planar_scans(bag.scans, replace(planar, mount=mount), names, str(args.bag))
    return ScanSequence(bag.times, scans, bag.odometry, str(args.bag)), notes + more


def _load_carmen(args):
    from mfcl_jax.io import read_carmen
    from mfcl_jax.io.tf_static import sensor_poses
    from mfcl_jax.sources.sequence import from_carmen

    log = read_carmen(args.carmen)
    seq = from_carmen(log, sensor_poses(log.odometry, mount_flags(args)[0]), str(args.carmen))
    notes = []
    if len(seq) < len(log):
        notes.append(
            f"{args.carmen}: {len(log) - len(seq)} lines whose time goes backwards were left out"
        )
    return seq, notes
