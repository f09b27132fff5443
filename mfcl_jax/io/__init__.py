"""Input/output: TUM trajectories, PCD scans, ROS bags (scans, PointCloud2
layouts, static transforms), CARMEN logs, decision logs, and safe atomic output; odometry
looked up at scan stamps (``timesync``) and scan units checked (``units``)."""

from mfcl_jax.io.atomic import atomic_write, check_output
from mfcl_jax.io.bag import BagScans, read_bag, read_tf_static
from mfcl_jax.io.carmen import CarmenLog, read_carmen
from mfcl_jax.io.decisions import read_decisions, write_decisions
from mfcl_jax.io.errors import DataError, DataWarning
from mfcl_jax.io.pcd import read_pcd, write_pcd
from mfcl_jax.io.pointcloud2 import pointcloud2_points
from mfcl_jax.io.tf_static import planar_pose, transform_between, xyz_rpy
from mfcl_jax.io.timesync import interpolate_se2, odometry_at
from mfcl_jax.io.tum import read_tum, write_tum

__all__ = [
    "BagScans",
    "CarmenLog",
    "DataError",
    "DataWarning",
    "atomic_write",
    "check_output",
    "interpolate_se2",
    "odometry_at",
    "planar_pose",
    "pointcloud2_points",
    "read_bag",
    "read_carmen",
    "read_decisions",
    "read_pcd",
    "read_tf_static",
    "read_tum",
    "transform_between",
    "write_decisions",
    "write_pcd",
    "write_tum",
    "xyz_rpy",
]
