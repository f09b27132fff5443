"""The input flags of ``mfcl localize``: sources, LiDAR mounting, the 3-D height band.

What they mean for the data: ``mfcl_jax.cli.inputs`` (which reads the inputs) and
``mfcl_jax.sources.planar`` (2-D or 3-D, the band).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

__all__ = ["lidar_offset_arg", "lidar_mount_arg", "add_input_flags", "add_band_flags"]


def _numbers(text: str, n: int, what: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"expected {what} ({n} finite numbers), got {text!r}")
    return vals


def lidar_offset_arg(text: str) -> tuple[float, float, float]:
    """``x,y,yaw_deg`` -> ``(x, y, yaw_rad)``."""
    x, y, yaw = _numbers(text, 3, "x,y,yaw_deg")
    return x, y, math.radians(yaw)


def lidar_mount_arg(text: str) -> tuple[float, ...]:
    """``x,y,z,roll_deg,pitch_deg,yaw_deg`` -> ``(x, y, z, roll, pitch, yaw)`` (m, rad)."""
    x, y, z, *rpy = _numbers(text, 6, "x,y,z,roll_deg,pitch_deg,yaw_deg")
    return (x, y, z, *(math.radians(a) for a in rpy))


def add_input_flags(lo) -> None:
    """The input flags of ``mfcl localize`` (sources, mounting, 3-D band)."""
    from mfcl_jax.cli.floorplan import add_rosmap_flags

    lo.add_argument(
        "dataset",
        type=Path,
        nargs="*",
        help="dataset folder(s) (floorplan.*, odometry.tum, scans/), or one folder holding "
        "dataset folders; omit with --bag/--carmen",
    )
    lo.add_argument(
        "--floorplan", type=Path, action="append",
        help="floor plan (.ifc/.geojson/.yaml); overrides the dataset's; give it once per storey "
        "for one plan per storey (e.g. ROS maps, each storey named by its file's stem)",
    )  # fmt: skip
    lo.add_argument("--bag", type=Path, help="ROS1 .bag or ROS2 bag folder instead of a dataset")
    lo.add_argument("--scan-topic", default="/scan", help="LaserScan/PointCloud2 topic (/scan)")
    lo.add_argument("--odom-topic", default="/odom", help="nav_msgs/Odometry topic (/odom)")
    lo.add_argument(
        "--carmen", type=Path, help="CARMEN log (.log/.log.gz; its odometry columns) instead"
    )
    lo.add_argument(
        "--lidar-offset",
        type=lidar_offset_arg,
        metavar="X,Y,YAW_DEG",
        help="LiDAR pose in the robot base frame (bags and CARMEN logs; m, m, deg)",
    )
    lo.add_argument(
        "--lidar-mount",
        type=lidar_mount_arg,
        metavar="X,Y,Z,ROLL,PITCH,YAW",
        help="full LiDAR pose on the robot (m, deg): x, y, yaw move the odometry as "
        "--lidar-offset (bags, CARMEN); z, roll, pitch level 3-D clouds (a dataset takes "
        "only those: x, y, yaw must be 0)",
    )
    lo.add_argument(
        "--tf-static",
        action="store_true",
        help="bags: read the LiDAR mounting from /tf_static (chain --base-frame -> scan frame)",
    )
    lo.add_argument("--base-frame", default="base_link", help="--tf-static parent (base_link)")
    add_rosmap_flags(lo)
    lo.add_argument("--storey", help="IFC storey name or elevation, GeoJSON level, or the stem "
                    "of one of several --floorplan files; default: every storey, and a commit "
                    "names the robot's")  # fmt: skip
    add_band_flags(lo)


def add_band_flags(lo) -> None:
    """The 3-D height band flags (``cli.inputs.planar_params`` reads them)."""
    g = lo.add_argument_group(
        "3-D clouds",
        "Scans whose z values span more than 0.3 m (median over the scans) are 3-D clouds: "
        "their points in a height band become the planar scan.",
    )
    g.add_argument("--band-min", type=float, help="band bottom (m; default 0.9)")
    g.add_argument("--band-max", type=float, help="band top (m; default 1.8)")
    g.add_argument(
        "--band-relative-to",
        choices=("floor", "sensor"),
        help="heights above the detected floor (default), or in the levelled sensor frame "
        "(raised by the mount's z)",
    )
    g.add_argument(
        "--no-band",
        action="store_true",
        help="project whole clouds onto x, y (the old behaviour; wrong for 3-D sensors: floor "
        "and ceiling become false walls)",
    )
    g.add_argument(
        "--input-dim", type=int, choices=(2, 3), help="2 or 3: override the z-extent rule"
    )
