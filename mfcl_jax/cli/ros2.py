"""``mfcl ros2``: the layer as a live ROS 2 node; ``mfcl play``: a dataset folder played onto
ROS 2 topics (to try the node without a robot). Thin: the work is in ``mfcl_jax.ros2``."""

from __future__ import annotations

import argparse
from pathlib import Path

from mfcl_jax.cli.flags import add_band_flags, lidar_mount_arg, lidar_offset_arg
from mfcl_jax.cli.progress_flag import add_progress_flag

__all__ = ["add_ros2_commands"]

ROS2_EPILOG = """\
topics (ROS 2 over DDS: Cyclone DDS from PyPI, no ROS installation; ROS_DOMAIN_ID and
CYCLONEDDS_URI apply as for any ROS 2 node):
  in   --scan-topic (sensor_msgs/LaserScan) or --cloud-topic (sensor_msgs/PointCloud2),
       best effort; --odom-topic (nav_msgs/Odometry, or /tf: --odom-frame -> --base-frame);
       /tf_static (the LiDAR mounting, --base-frame -> the scans' frame), unless
       --lidar-offset / --lidar-mount give it
  out  /initialpose (geometry_msgs/PoseWithCovarianceStamped, frame --map-frame = the
       floor plan's frame, reliable, latched): the robot's base pose at the first COMMIT
       of each odometry segment, with the covariance of the fit (nav2's AMCL takes it);
       /mfcl/status (std_msgs/String): a JSON object per window (the decisions-file line)
       and per event (start, silent, restart, warning, stop); with --publish-tf also
       map -> odom on /tf

faults: a topic silent for --silence s: a DEFER event on /mfcl/status (never a guess);
  stamps going back in time (a bag played again): a new segment, the layer starts over;
  a message that cannot be read: a warning, the message left out.

stopping: Ctrl-C or SIGTERM writes --out and --viz (what was decided), exit 130 / 143.
exit status: 2 bad input (the plan, a flag), 130 / 143 stopped by a signal."""


def add_ros2_commands(subparsers) -> None:
    """Adds ``ros2`` (the node) and ``play`` (a dataset onto topics)."""
    ro = subparsers.add_parser(
        "ros2",
        help="run as a live ROS 2 node: the robot's scans and odometry in, /initialpose out",
        description="Localize a robot live from its ROS 2 topics and publish its pose for "
        "nav2 once the layer commits.",
        epilog=ROS2_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ro.add_argument("--floorplan", type=Path, required=True, action="append",
                    help="floor plan (.ifc/.geojson/.yaml): the frame of --map-frame; once per "
                    "storey for one map per storey (each named by its file's stem)")  # fmt: skip
    ro.add_argument(
        "--storey",
        help="IFC storey name or elevation, GeoJSON level, or a "
        "--floorplan stem; default: every storey (a commit names the robot's)",
    )
    scan = ro.add_mutually_exclusive_group()
    scan.add_argument("--scan-topic", default="/scan", help="LaserScan topic (/scan)")
    scan.add_argument("--cloud-topic", help="PointCloud2 topic instead of a LaserScan topic")
    ro.add_argument(
        "--odom-topic",
        default="/odom",
        help="nav_msgs/Odometry topic, or /tf for odom -> base transforms (/odom)",
    )
    ro.add_argument("--odom-frame", default="odom", help="odometry frame (odom)")
    ro.add_argument("--base-frame", default="base_link", help="robot base frame (base_link)")
    ro.add_argument("--map-frame", default="map", help="frame of the published pose (map)")
    ro.add_argument(
        "--lidar-offset",
        type=lidar_offset_arg,
        metavar="X,Y,YAW_DEG",
        help="LiDAR pose on the base (m, m, deg) instead of /tf_static",
    )
    ro.add_argument(
        "--lidar-mount",
        type=lidar_mount_arg,
        metavar="X,Y,Z,ROLL,PITCH,YAW",
        help="full LiDAR pose on the base (m, deg) instead of /tf_static",
    )
    ro.add_argument(
        "--silence",
        type=float,
        default=5.0,
        metavar="S",
        help="a topic without messages for S seconds is reported silent (5)",
    )
    ro.add_argument(
        "--publish-tf",
        action="store_true",
        help="also publish map -> odom on /tf once committed (stacks without AMCL)",
    )
    ro.add_argument("--pose-topic", default="/initialpose", help="(/initialpose)")
    ro.add_argument("--status-topic", default="/mfcl/status", help="(/mfcl/status)")
    ro.add_argument("--d-s", type=float, default=6.0, help="window length in metres (6)")
    ro.add_argument(
        "--early-commit",
        type=float,
        metavar="ALPHA",
        choices=(1e-1, 1e-2, 1e-3, 1e-4, 1e-6),
        help="as mfcl localize --early-commit",
    )
    ro.add_argument(
        "--no-scan-match",
        action="store_true",
        help="as mfcl localize --no-scan-match (odometry from a LIO)",
    )
    ro.add_argument("--out", type=Path, help="also write the decisions (JSON lines) on exit")
    ro.add_argument("--viz", type=Path, metavar="FILE.mcap", help="also write an MCAP on exit")
    ro.add_argument(
        "--foxglove",
        type=int,
        nargs="?",
        const=8765,
        metavar="PORT",
        help="serve the --viz content live over Foxglove's WebSocket protocol on "
        "PORT (8765): open ws://HOST:PORT in Foxglove to watch the layer decide",
    )
    ro.add_argument(
        "--foxglove-host",
        default="127.0.0.1",
        help="address the Foxglove server listens on (127.0.0.1: this machine; 0.0.0.0: any)",
    )
    ro.add_argument("--quiet", action="store_true", help="no per-window status lines on stderr")
    ro.add_argument(
        "--reliable",
        action="store_true",
        help="read the scan and odometry topics reliably (their writers must be reliable, "
        "as mfcl play --reliable is): nothing lost on a loaded machine; the default, best "
        "effort, matches any writer, as nav2's sensor subscriptions do",
    )
    from mfcl_jax.cli.floorplan import add_rosmap_flags

    add_rosmap_flags(ro)
    add_band_flags(ro)
    add_progress_flag(ro)
    ro.set_defaults(func=_cmd_ros2)

    pl = subparsers.add_parser(
        "play",
        help="publish a dataset folder onto ROS 2 topics (try mfcl ros2 without a robot)",
        description="Publish a dataset folder's scans (LaserScan or PointCloud2), its "
        "odometry (nav_msgs/Odometry or /tf) and the LiDAR mounting (/tf_static) in time "
        "order, as a robot does; or a ROS bag's (--bag).",
    )
    pl.add_argument("dataset", type=Path, nargs="?", help="dataset folder (odometry.tum, scans/)")
    pl.add_argument(
        "--bag",
        type=Path,
        help="a ROS 1 or ROS 2 bag instead: its --scan-topic, "
        "--odom-topic and /tf_static messages, as recorded",
    )
    pl.add_argument("--rate", type=float, default=1.0, help="times real time (1)")
    pl.add_argument("--scan-topic", default="/scan", help="(/scan)")
    pl.add_argument("--cloud", action="store_true", help="scans as PointCloud2")
    pl.add_argument("--odom-topic", default="/odom", help="/odom (Odometry) or /tf")
    pl.add_argument(
        "--reliable",
        action="store_true",
        help="write scans and odometry reliably, keep all (for mfcl ros2 --reliable)",
    )
    pl.add_argument("--lidar-offset", type=lidar_offset_arg, metavar="X,Y,YAW_DEG",
                    default=(0.0, 0.0, 0.0), help="LiDAR pose on the base published on "
                    "/tf_static (the odometry published is the base's)")  # fmt: skip
    pl.add_argument(
        "--wait",
        type=float,
        default=10.0,
        metavar="S",
        help="wait up to S seconds for a reader of the topics before playing (10)",
    )
    pl.add_argument(
        "--time-offset", type=float, default=0.0, metavar="S", help="add S seconds to every stamp"
    )
    pl.set_defaults(func=_cmd_play)


def _cmd_ros2(args) -> int:
    from mfcl_jax.robot.progress import Progress
    from mfcl_jax.ros2.run import run_node

    return run_node(args, Progress(True if args.progress else None))


def _cmd_play(args) -> int:
    from mfcl_jax.ros2.run import run_play

    return run_play(args)
