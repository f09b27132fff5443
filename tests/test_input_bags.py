"""Issue 29 in ROS bags: odometry at 100 Hz (or from /tf) matched to the scans by time,
quaternions scaled by 2 or degenerate, millimetre clouds refused."""

from __future__ import annotations

import numpy as np
import pytest
from _bags import VELODYNE, odometry, pointcloud2, quat_yaw, store, tf_message, write_bag

from mfcl_jax.io import DataError, read_bag
from mfcl_jax.io.errors import DataWarning
from tests._inputs import T0, _quiet, _scan_times, _truth, _yaw_err

TS1 = store(ros1=True)
PC2 = "sensor_msgs/msg/PointCloud2"
ODOM = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"


def _cloud(t, k=1.0):
    xyz = np.random.default_rng(int(t * 10)).uniform(-8, 8, size=(16, 3)).astype(np.float32)
    return pointcloud2(TS1, t, k * xyz, VELODYNE)


def _bag(tmp_path, odom_msgs, k=1.0, name="r.bag"):
    scans = [("/points", PC2, t, _cloud(t, k)) for t in _scan_times(10)]
    return write_bag(tmp_path / name, TS1, odom_msgs + scans)


def _odom_msgs(times, q_scale=1.0):
    return [
        ("/odom", ODOM, t, odometry(TS1, t, *map(float, _truth(t)), q_scale=q_scale)) for t in times
    ]


def test_bag_odom_at_100hz_interpolated_and_outside_scans_warned(tmp_path):
    t100 = T0 + 0.2 + 0.01 * np.arange(81)  # scans 2..9 of 10 inside
    path = _bag(tmp_path, _odom_msgs(t100))
    with pytest.warns(DataWarning, match=r"r\.bag /odom: 2 of 10 scans lie outside"):
        bag = read_bag(path, scan_topic="/points")
    assert len(bag) == 8 and bag.unpaired == 2
    np.testing.assert_allclose(bag.odometry[:, :2], _truth(bag.times)[:, :2], atol=1e-6)
    assert _yaw_err(bag.odometry[:, 2], _truth(bag.times)[:, 2]) < 1e-6


def test_bag_odometry_quaternions_scaled_by_2(tmp_path):
    t100 = T0 + 0.01 * np.arange(101)
    path = _bag(tmp_path, _odom_msgs(t100, q_scale=2.0))
    with pytest.warns(DataWarning, match=r"r\.bag /odom t=1000\.0+: quaternion norm 2 differs"):
        bag = read_bag(path, scan_topic="/points")
    assert _yaw_err(bag.odometry[:, 2], _truth(bag.times)[:, 2]) < 1e-6
    zero = _bag(tmp_path, _odom_msgs(t100, q_scale=0.0), name="z.bag")
    with pytest.raises(DataError, match=r"z\.bag /odom t=1000\.0+: degenerate quaternion"):
        read_bag(zero, scan_topic="/points")


def test_bag_odometry_from_tf(tmp_path):
    t100 = T0 + 0.01 * np.arange(101)
    tfs = [
        ("/tf", TF, t, tf_message(TS1, [("odom", "base_link", (*_truth(t)[:2], 0.0),
                                         quat_yaw(_truth(t)[2]))], t=t))
        for t in t100
    ]  # fmt: skip
    path = _bag(tmp_path, tfs)
    bag = _quiet(read_bag, path, scan_topic="/points", odom_topic="/tf")
    np.testing.assert_allclose(bag.odometry[:, :2], _truth(bag.times)[:, :2], atol=1e-6)
    assert _yaw_err(bag.odometry[:, 2], _truth(bag.times)[:, 2]) < 1e-6
    with pytest.raises(DataError, match=r"no transform map -> base_link; .* odom -> base_link"):
        read_bag(path, scan_topic="/points", odom_topic="/tf", odom_frames=("map", "base_link"))


def test_bag_millimetre_scans_refused(tmp_path):
    path = _bag(tmp_path, _odom_msgs(T0 + 0.01 * np.arange(101)), k=1000.0)
    with pytest.raises(DataError) as e:
        read_bag(path, scan_topic="/points")
    assert "r.bag /points scan at t=1000.003700000" in str(e.value)
    assert "millimetres" in str(e.value) and "expects scans in metres" in str(e.value)
