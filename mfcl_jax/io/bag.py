"""ROS1/ROS2 bags (via ``rosbags``): 2D scans paired with odometry.

Scans are ``sensor_msgs/LaserScan`` (valid ranges within ``[range_min, range_max]``) or
``sensor_msgs/PointCloud2`` (fields ``x``, ``y``; non-finite points dropped), taken at their
header stamps. Odometry is ``nav_msgs/Odometry``; its planar pose is interpolated at each
scan stamp (linear in x, y and in the unwrapped yaw). Scans outside the odometry's time span
cannot be paired: they are left out and counted in ``BagScans.unpaired``. The odometry pose
is the pose of the odometry's child frame; a fixed sensor mounting can be given as
``sensor_offset``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.tum import yaw_from_quat

__all__ = ["BagScans", "read_bag"]


@dataclass(frozen=True, eq=False)
class BagScans:
    """Scans of a bag with the odometry at their stamps.

    Attributes:
        times: ``(N,)`` scan stamps (s).
        scans: ``N`` arrays ``(n_i, 2)``, points in the sensor frame.
        odometry: ``(N, 3)`` sensor poses in the odometry frame at the scan stamps.
        unpaired: scans left out because no odometry brackets their stamp.
        odom_times: ``(M,)`` stamps of the raw odometry messages.
        odom_poses: ``(M, 3)`` the raw odometry poses.
    """

    times: np.ndarray
    scans: list[np.ndarray]
    odometry: np.ndarray
    unpaired: int
    odom_times: np.ndarray
    odom_poses: np.ndarray

    def __len__(self) -> int:
        return len(self.times)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _laserscan_points(m) -> np.ndarray:
    r = np.asarray(m.ranges, float)
    a = m.angle_min + m.angle_increment * np.arange(len(r))
    ok = np.isfinite(r) & (r >= m.range_min) & (r <= m.range_max)
    return np.stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])], -1)


_PC2_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def _pointcloud2_points(m, where: str) -> np.ndarray:
    fields = {f.name: f for f in m.fields}
    for name in ("x", "y"):
        if name not in fields:
            raise DataError(f"{where}: PointCloud2 without field {name!r} ({list(fields)})")
    end = ">" if m.is_bigendian else "<"
    data = np.frombuffer(bytes(m.data), np.uint8)
    n = m.width * m.height
    rows = data[: n * m.point_step].reshape(n, m.point_step) if n else data[:0].reshape(0, 1)
    cols = []
    for name in ("x", "y"):
        f = fields[name]
        dt = np.dtype(end + _PC2_TYPES[f.datatype])
        cols.append(rows[:, f.offset : f.offset + dt.itemsize].copy().view(dt).reshape(-1))
    xy = np.stack(cols, -1).astype(float)
    return xy[np.all(np.isfinite(xy), axis=1)]


def read_bag(
    path, scan_topic: str = "/scan", odom_topic: str = "/odom", sensor_offset=(0.0, 0.0, 0.0)
) -> BagScans:
    """Reads scans and odometry from a ROS1 ``.bag`` or a ROS2 bag folder.

    Args:
        path: the bag.
        scan_topic: LaserScan or PointCloud2 topic.
        odom_topic: nav_msgs/Odometry topic.
        sensor_offset: pose ``(x, y, yaw)`` of the sensor in the odometry child frame.

    Raises:
        DataError: unreadable bag, a missing topic or a topic of the wrong type (the topics
            present are listed), no scan that the odometry brackets.
    """
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: bag not found")
    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as e:
        raise DataError(f"{path}: not a readable ROS bag ({type(e).__name__}: {e})") from None
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        listing = ", ".join(f"{t} ({ty})" for t, ty in sorted(topics.items())) or "none"
        for topic, ok_types in (
            (scan_topic, ("sensor_msgs/msg/LaserScan", "sensor_msgs/msg/PointCloud2")),
            (odom_topic, ("nav_msgs/msg/Odometry",)),
        ):
            if topic not in topics:
                raise DataError(f"{path}: no topic {topic!r}; topics present: {listing}")
            if topics[topic] not in ok_types:
                want = " or ".join(ok_types)
                raise DataError(f"{path}: topic {topic!r} carries {topics[topic]}, expected {want}")
        conns = [c for c in reader.connections if c.topic in (scan_topic, odom_topic)]
        s_t, scans, o_t, o_p = [], [], [], []
        for con, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, con.msgtype)
            if con.topic == odom_topic:
                p, q = m.pose.pose.position, m.pose.pose.orientation
                o_t.append(_stamp(m))
                o_p.append((p.x, p.y, float(yaw_from_quat([q.x, q.y, q.z, q.w]))))
            elif con.msgtype.endswith("LaserScan"):
                s_t.append(_stamp(m))
                scans.append(_laserscan_points(m))
            else:
                s_t.append(_stamp(m))
                scans.append(_pointcloud2_points(m, f"{path} {scan_topic}"))
    finally:
        reader.close()
    return _pair(
        path, np.asarray(s_t), scans, np.asarray(o_t), np.asarray(o_p).reshape(-1, 3), sensor_offset
    )


def _pair(path, s_t, scans, o_t, o_p, offset) -> BagScans:
    order = np.argsort(o_t, kind="stable")
    o_t, o_p = o_t[order], o_p[order]
    keep = np.unique(o_t, return_index=True)[1]  # duplicate stamps: first message wins
    o_t, o_p = o_t[keep], o_p[keep]
    if len(o_t) < 2:
        raise DataError(f"{path}: need at least 2 odometry messages, got {len(o_t)}")
    s_order = np.argsort(s_t, kind="stable")
    s_t = s_t[s_order]
    scans = [scans[i] for i in s_order]
    inside = (s_t >= o_t[0]) & (s_t <= o_t[-1])
    if not inside.any():
        raise DataError(
            f"{path}: no scan stamp lies within the odometry's span [{o_t[0]:.3f}, {o_t[-1]:.3f}] s"
        )
    t = s_t[inside]
    yaw = np.unwrap(o_p[:, 2])
    pose = np.stack(
        [np.interp(t, o_t, o_p[:, 0]), np.interp(t, o_t, o_p[:, 1]), np.interp(t, o_t, yaw)], -1
    )
    ox, oy, oth = (float(v) for v in offset)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    pose = np.stack(
        [pose[:, 0] + c * ox - s * oy, pose[:, 1] + s * ox + c * oy, pose[:, 2] + oth], -1
    )
    pose[:, 2] = np.arctan2(np.sin(pose[:, 2]), np.cos(pose[:, 2]))
    return BagScans(
        t,
        [scans[i] for i in np.flatnonzero(inside)],
        pose,
        int(np.count_nonzero(~inside)),
        o_t,
        o_p,
    )
