"""What ``mfcl localize`` reads: a dataset folder, a ROS bag or a CARMEN log, with a floor plan.

Odometry convention: the localizer wants SENSOR poses in L. A dataset's ``odometry.tum`` is
already the sensor pose (no mounting is applied to it). A bag's or CARMEN log's odometry is
the robot base's: ``--lidar-offset x,y,yaw_deg`` (or, for bags, ``--tf-static``: the
``/tf_static`` chain from ``--base-frame`` to the scans' frame, its planar part) is composed
onto it so that the odometry poses become sensor poses.

Anchors in the decision log are in the floor plan's file frame: a plan far from the origin
is localized in a local frame (``mfcl_jax.floorplan.origin``) and its anchors are moved back
(float64, full precision in the JSON).
"""

from __future__ import annotations

import argparse
import math

__all__ = ["lidar_offset_arg", "input_paths", "load_input", "plan_frame_decision"]


def lidar_offset_arg(text: str) -> tuple[float, float, float]:
    """``x,y,yaw_deg`` -> ``(x, y, yaw_rad)``."""
    parts = text.split(",")
    try:
        vals = [float(v) for v in parts]
    except ValueError:
        vals = []
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"expected x,y,yaw_deg (3 finite numbers), got {text!r}")
    return vals[0], vals[1], math.radians(vals[2])


def input_paths(args) -> list:
    """Every file or folder the localize run reads (the output must be none of them)."""
    from mfcl_jax.floorplan.load import floorplan_files
    from mfcl_jax.io.dataset import FLOORPLAN_NAMES

    paths = [args.bag, args.carmen]
    plans = [args.floorplan] if args.floorplan is not None else []
    if args.dataset is not None:
        d = args.dataset
        paths += [d / "odometry.tum", d / "groundtruth.tum", d / "scans"]
        plans += [d / n for n in FLOORPLAN_NAMES]
    return paths + [f for p in plans for f in floorplan_files(p)]


def load_input(args):
    """(floorplan, ScanSequence, notes) from a dataset folder, a bag or a CARMEN log; the
    notes say what was dropped or applied on the way."""
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.io import DataError, load_dataset, read_bag, read_carmen
    from mfcl_jax.io.tf_static import planar_pose, sensor_poses
    from mfcl_jax.sources.sequence import from_bag, from_carmen, from_dataset

    sources = (("DATASET", args.dataset), ("--bag", args.bag), ("--carmen", args.carmen))
    given = [name for name, v in sources if v is not None]
    if not given:
        raise DataError("localize: give a DATASET folder or --bag B (with --floorplan F)")
    if args.bag is not None and args.dataset is not None:
        raise DataError(f"localize: give either DATASET ({args.dataset}) or --bag ({args.bag})")
    if len(given) > 1:
        raise DataError(f"localize: give one input, got {' and '.join(given)}")
    if args.tf_static and args.bag is None:
        raise DataError("localize: --tf-static reads /tf_static from a bag; give --bag")
    if args.tf_static and args.lidar_offset is not None:
        raise DataError("localize: give the LiDAR mounting by --lidar-offset or --tf-static")
    if args.dataset is not None and args.lidar_offset is not None:
        raise DataError(
            f"{args.dataset}: odometry.tum is already the sensor pose; --lidar-offset applies "
            "to --bag and --carmen"
        )
    opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    fp = None
    if args.floorplan is not None:
        fp = load_floorplan(args.floorplan, storey=args.storey, **opts)
    notes = []
    if args.bag is not None or args.carmen is not None:
        src = args.bag if args.bag is not None else args.carmen
        if fp is None:
            kind = "bag" if args.bag is not None else "CARMEN log"
            raise DataError(f"{src}: a {kind} has no floor plan; pass --floorplan F")
    offset = args.lidar_offset or (0.0, 0.0, 0.0)
    if args.bag is not None:
        bag = read_bag(
            args.bag,
            args.scan_topic,
            args.odom_topic,
            sensor_offset=offset,
            base_frame=args.base_frame if args.tf_static else None,
        )
        if args.tf_static:
            x, y, yaw = planar_pose(bag.mount)
            notes.append(
                f"LiDAR mounting from /tf_static, {args.base_frame} -> {bag.frame_id}: "
                f"x={x:.3f} m, y={y:.3f} m, yaw={math.degrees(yaw):.2f} deg"
            )
        for what, k in (
            ("scans repeating an earlier scan's stamp were left out", bag.duplicates),
            ("odometry messages repeating a stamp were left out", bag.odom_duplicates),
            ("scans outside the odometry's time span were left out", bag.unpaired),
            ("non-finite or zero points were dropped", bag.dropped),
        ):
            if k:
                notes.append(f"{args.bag}: {k} {what}")
        return fp, from_bag(bag, str(args.bag)), notes
    if args.carmen is not None:
        log = read_carmen(args.carmen)
        seq = from_carmen(log, sensor_poses(log.odometry, offset), str(args.carmen))
        if len(seq) < len(log):
            notes.append(
                f"{args.carmen}: {len(log) - len(seq)} lines whose time goes backwards were "
                "left out"
            )
        return fp, seq, notes
    ds = load_dataset(args.dataset, storey=args.storey, floorplan=fp, **opts)
    if int(ds.dropped.sum()):
        notes.append(
            f"{args.dataset}: {int(ds.dropped.sum())} non-finite points dropped from "
            f"{int((ds.dropped > 0).sum())} scans"
        )
    return ds.floorplan, from_dataset(ds), notes


def plan_frame_decision(decision: dict, offset) -> dict:
    """The decision with its anchor moved from the local frame to the plan's file frame."""
    a = decision["anchor"]
    if a is None or not any(offset):
        return decision
    from mfcl_jax.floorplan.origin import to_plan_frame

    x, y = (float(v) for v in to_plan_frame([a["x"], a["y"]], offset))
    return dict(decision, anchor=dict(a, x=x, y=y))
