"""ROS bags: PointCloud2 of Livox / Velodyne / Ouster layouts, duplicate scan stamps,
the LiDAR mounting from /tf_static (ROS1 and ROS2)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from _bags import (
    LIVOX,
    OUSTER,
    VELODYNE,
    odometry,
    pointcloud2,
    quat_yaw,
    store,
    tf_message,
    write_bag,
)

from mfcl_jax.io import (
    DataError,
    pointcloud2_points,
    read_bag,
    read_tf_static,
    transform_between,
    xyz_rpy,
)
from mfcl_jax.io.tf_static import planar_pose

TS1 = store(ros1=True)
PC2 = "sensor_msgs/msg/PointCloud2"
ODOM = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"


def _xyz(n=24, seed=0):
    return np.random.default_rng(seed).uniform(-20, 20, size=(n, 3)).astype(np.float32)


@pytest.mark.parametrize("layout", [LIVOX, VELODYNE, OUSTER], ids=["livox", "velodyne", "ouster"])
@pytest.mark.parametrize("bigendian", [False, True])
def test_layouts_give_xyz(layout, bigendian):
    xyz = _xyz()
    msg = pointcloud2(TS1, 1.0, xyz, layout, bigendian=bigendian)
    pts, dropped = pointcloud2_points(msg, "b.bag /points", xyz=True)
    np.testing.assert_array_equal(pts, xyz.astype(float))
    assert dropped == 0
    xy, _ = pointcloud2_points(msg, "b.bag /points")
    np.testing.assert_array_equal(xy, xyz[:, :2].astype(float))


def test_organised_cloud_with_row_padding_nan_and_zero_points():
    xyz = _xyz(32)
    xyz[3] = np.nan  # organised clouds mark no-returns with NaN
    xyz[7] = 0.0  # Ouster writes them as zeros
    msg = pointcloud2(TS1, 1.0, xyz, OUSTER, height=4, extra_row_bytes=6)
    pts, dropped = pointcloud2_points(msg, "o.bag /os_cloud", xyz=True)
    keep = np.ones(32, bool)
    keep[[3, 7]] = False
    np.testing.assert_array_equal(pts, xyz[keep].astype(float))
    assert dropped == 2


def _fake(fields, **kw):
    base = dict(height=1, width=2, point_step=12, row_step=24, is_bigendian=False)
    base.update(kw)
    base.setdefault("data", np.zeros(base["row_step"] * base["height"], np.uint8))
    f = [SimpleNamespace(name=n, offset=o, datatype=d, count=1) for n, o, d in fields]
    return SimpleNamespace(fields=f, **base)


@pytest.mark.parametrize(
    "msg, words",
    [
        (_fake([("x", 0, 7), ("y", 4, 7)]), "without field 'z' (['x', 'y'])"),
        (_fake([("x", 0, 7), ("y", 4, 7), ("z", 10, 7)]), "field 'z' at offset 10"),
        (_fake([("x", 0, 7), ("y", 4, 7), ("z", 8, 9)]), "field 'z' has unknown datatype 9"),
        (
            _fake(
                [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], row_step=20, data=np.zeros(24, np.uint8)
            ),
            "row_step 20 is shorter",
        ),  # fmt: skip
        (
            _fake([("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], data=np.zeros(20, np.uint8)),
            "data holds 20 bytes",
        ),  # fmt: skip
    ],
)
def test_pointcloud2_errors(msg, words):
    with pytest.raises(DataError) as e:
        pointcloud2_points(msg, "x.bag /points", xyz=True)
    assert "x.bag /points" in str(e.value) and words in str(e.value)


def _odom(t0=0.0, t1=5.0, n=11):
    return [
        ("/odom", ODOM, t, odometry(TS1, t, 0.5 * t, 0.0, 0.1 * t)) for t in np.linspace(t0, t1, n)
    ]


def test_duplicate_scan_stamps_keep_the_first(tmp_path):
    scans = [(1.0, _xyz(5, 1)), (2.0, _xyz(5, 2)), (2.0, _xyz(5, 3)), (3.0, _xyz(5, 4))]
    msgs = _odom() + [("/points", PC2, t, pointcloud2(TS1, t, x, VELODYNE)) for t, x in scans]
    msgs += [("/odom", ODOM, 2.5, odometry(TS1, 2.5, 1.25, 0.0, 0.25))]  # repeats t=2.5
    path = write_bag(tmp_path / "d.bag", TS1, msgs)
    bag = read_bag(path, scan_topic="/points", xyz=True)
    assert len(bag) == 3 and bag.duplicates == 1 and bag.odom_duplicates == 1
    np.testing.assert_array_equal(bag.times, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(bag.scans[1], scans[1][1].astype(float))  # the first wins
    assert bag.frame_id == "lidar" and bag.scans[0].shape == (5, 3)


MOUNT = [
    ("base_link", "lidar_mount", (0.2, 0.0, 1.0), quat_yaw(math.pi / 2)),
    ("lidar_mount", "os_sensor", (0.1, 0.0, 0.2), quat_yaw(0.0)),
]


def _mounted_bag(tmp_path, ros1=True, frame="os_sensor"):
    ts = store(ros1)
    msgs = [("/tf_static", TF, 0.0, tf_message(ts, MOUNT))]
    msgs += [
        ("/odom", ODOM, t, odometry(ts, t, 0.5 * t, 0.0, 0.1 * t)) for t in np.linspace(0, 5, 11)
    ]
    msgs += [
        ("/points", PC2, t, pointcloud2(ts, t, _xyz(8, int(t)), OUSTER, frame=frame))
        for t in (1.0, 2.0, 3.0)
    ]
    name = "m.bag" if ros1 else "m_ros2"
    return write_bag(tmp_path / name, ts, msgs, ros1=ros1)


@pytest.mark.parametrize("ros1", [True, False], ids=["ros1", "ros2"])
def test_mounting_from_tf_static(tmp_path, ros1):
    path = _mounted_bag(tmp_path, ros1)
    edges = read_tf_static(path)
    T = transform_between(edges, "base_link", "os_sensor")
    # lidar_mount is turned 90 deg: its x offset of 0.1 m points along base_link's y.
    np.testing.assert_allclose(xyz_rpy(T), [0.2, 0.1, 1.2, 0, 0, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(
        transform_between(edges, "os_sensor", "base_link"), np.linalg.inv(T), atol=1e-12
    )
    bag = read_bag(path, scan_topic="/points", base_frame="base_link")
    plain = read_bag(path, scan_topic="/points")
    np.testing.assert_allclose(bag.mount, T)
    x, y, yaw = plain.odometry.T
    c, s = np.cos(yaw), np.sin(yaw)
    expect = np.stack([x + c * 0.2 - s * 0.1, y + s * 0.2 + c * 0.1, yaw + math.pi / 2], -1)
    np.testing.assert_allclose(bag.odometry, expect, atol=1e-9)
    np.testing.assert_allclose(planar_pose(T), [0.2, 0.1, math.pi / 2], atol=1e-12)


def test_tf_static_errors(tmp_path):
    path = _mounted_bag(tmp_path, frame="velodyne")
    with pytest.raises(DataError) as e:
        read_bag(path, scan_topic="/points", base_frame="base_link")
    msg = str(e.value)
    assert "m.bag /tf_static" in msg and "'base_link' to 'velodyne'" in msg
    assert "frames present: base_link, lidar_mount, os_sensor" in msg
    with pytest.raises(DataError, match="not both"):
        read_bag(path, scan_topic="/points", sensor_offset=(1, 0, 0), base_frame="base_link")
    plain = write_bag(tmp_path / "p.bag", TS1, _odom())
    with pytest.raises(DataError, match=r"p\.bag: no topic '/tf_static'; topics present: /odom"):
        read_tf_static(plain)
