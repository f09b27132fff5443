"""ROS1/ROS2 bags (via ``rosbags``): scans paired with odometry.

Scans are ``sensor_msgs/LaserScan`` (valid ranges within ``[range_min, range_max]``) or
``sensor_msgs/PointCloud2`` (any driver's layout, ``mfcl_jax.io.pointcloud2``), taken at
their header stamps; ``xyz=True`` keeps z (LaserScan points get z = 0). Scans that repeat an
earlier scan's stamp are left out (the first message wins) and counted in
``BagScans.duplicates``, as duplicate odometry stamps are (``odom_duplicates``).

Odometry comes at its own rate, from ``nav_msgs/Odometry`` messages (``/odom``) or from the
``tf2_msgs/TFMessage`` transforms of a ``/tf`` topic (those from ``odom_frames[0]`` to
``odom_frames[1]``, e.g. ``odom -> base_link``; given as ``odom_topic="/tf"``). Its quaternions
are checked as a TUM file's are (``io.tum.unit_quaternions``: normalised with a
``DataWarning``, refused when degenerate). Its planar pose is looked up at each scan stamp by
``io.timesync.odometry_at`` (SE(2) interpolation, 1 ms tolerance at the ends of its span),
the same code that pairs a dataset's scans; scans outside the odometry's time span are left
out with a ``DataWarning`` and counted in ``BagScans.unpaired``. Scans whose ranges look like
millimetres are refused (``io.units.check_metres``).

The odometry pose is the pose of the odometry's child frame (the robot's base). The sensor
pose is that pose composed with the LiDAR mounting: given as ``sensor_offset`` ``(x, y,
yaw)``, or read from the bag's ``/tf_static`` with ``base_frame`` (the chain from that frame
to the scans' ``header.frame_id``; its planar part is applied, the full 4x4 is kept in
``BagScans.mount``). ``BagScans.odometry`` is then the SENSOR pose in L, the convention of
every ``ScanSequence``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.pointcloud2 import pointcloud2_points
from mfcl_jax.io.tf_static import planar_pose, sensor_poses, static_edges, transform_between
from mfcl_jax.io.timesync import odometry_at
from mfcl_jax.io.tum import unit_quaternions, yaw_from_quat
from mfcl_jax.io.units import check_metres, check_some_points

__all__ = ["read_tf_static", "BagScans", "read_bag", "open_bag", "laserscan_points"]

_SCAN_TYPES = ("sensor_msgs/msg/LaserScan", "sensor_msgs/msg/PointCloud2")
_ODOM_TYPES = ("nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage")


@dataclass(frozen=True, eq=False)
class BagScans:
    """Scans of a bag with the odometry at their stamps.

    Attributes:
        times: ``(N,)`` scan stamps (s), strictly increasing.
        scans: ``N`` arrays ``(n_i, 2)`` (or ``(n_i, 3)`` with ``xyz``), sensor frame.
        odometry: ``(N, 3)`` sensor poses in the odometry frame at the scan stamps.
        unpaired: scans left out because they lie outside the odometry's time span (more
            than ``timesync.TIME_TOL_S`` beyond its ends; a ``DataWarning`` says so).
        odom_times: ``(M,)`` stamps of the raw odometry messages (duplicates removed).
        odom_poses: ``(M, 3)`` the raw odometry poses.
        duplicates: scans left out because an earlier scan has the same stamp.
        odom_duplicates: odometry messages left out for the same reason.
        dropped: points dropped from PointCloud2 scans (non-finite or at the origin).
        frame_id: the scans' ``header.frame_id`` (of the first scan).
        mount: ``(4, 4)`` sensor pose in ``base_frame`` from ``/tf_static``, or None.
    """

    times: np.ndarray
    scans: list[np.ndarray]
    odometry: np.ndarray
    unpaired: int
    odom_times: np.ndarray
    odom_poses: np.ndarray
    duplicates: int = 0
    odom_duplicates: int = 0
    dropped: int = 0
    frame_id: str = ""
    mount: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.times)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


class _Odometry:
    """Collects odometry rows ``(t, x, y, qx, qy, qz, qw)`` from Odometry or TF messages."""

    def __init__(self, frames: tuple[str, str]):
        self.frames = tuple(str(f).lstrip("/") for f in frames)
        self.rows: list[tuple] = []
        self.pairs: set[tuple[str, str]] = set()

    def add(self, m) -> None:
        if not hasattr(m, "transforms"):
            p, q = m.pose.pose.position, m.pose.pose.orientation
            self.rows.append((_stamp(m), p.x, p.y, q.x, q.y, q.z, q.w))
            return
        for ts in m.transforms:
            pair = (ts.header.frame_id.lstrip("/"), ts.child_frame_id.lstrip("/"))
            self.pairs.add(pair)
            if pair == self.frames:
                tr, q = ts.transform.translation, ts.transform.rotation
                self.rows.append((_stamp(ts), tr.x, tr.y, q.x, q.y, q.z, q.w))

    def poses(self, where: str) -> tuple[np.ndarray, np.ndarray]:
        """``(times (M,), poses (M, 3))`` in message order, quaternions checked."""
        if not self.rows and self.pairs:
            pairs = ", ".join(f"{a} -> {b}" for a, b in sorted(self.pairs))
            raise DataError(
                f"{where}: no transform {self.frames[0]} -> {self.frames[1]}; transforms "
                f"present: {pairs}"
            )
        r = np.asarray(self.rows, np.float64).reshape(-1, 7)
        q = unit_quaternions(r[:, 3:], [f"{where} t={t:.9f}" for t in r[:, 0]])
        return r[:, 0], np.stack([r[:, 1], r[:, 2], yaw_from_quat(q)], -1)


def laserscan_points(m, xyz: bool) -> np.ndarray:
    """The points of a ``sensor_msgs/LaserScan`` (returns within ``[range_min, range_max]``;
    a bag's or a live topic's message), ``(n, 2)`` or ``(n, 3)`` with z = 0."""
    r = np.asarray(m.ranges, float)
    a = m.angle_min + m.angle_increment * np.arange(len(r))
    ok = np.isfinite(r) & (r >= m.range_min) & (r <= m.range_max)
    cols = [r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])]
    return np.stack(cols + [np.zeros(int(ok.sum()))] if xyz else cols, -1)


def open_bag(path):
    """An opened ``rosbags`` AnyReader (close it after use).

    Raises:
        DataError: a missing path or a file that is not a readable bag.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: bag not found")
    try:
        # The default store reads ROS2 bags that do not embed their message definitions.
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as e:
        raise DataError(f"{path}: not a readable ROS bag ({type(e).__name__}: {e})") from None
    return reader


def read_bag(
    path,
    scan_topic: str = "/scan",
    odom_topic: str = "/odom",
    sensor_offset=(0.0, 0.0, 0.0),
    xyz: bool = False,
    base_frame: str | None = None,
    tf_topic: str = "/tf_static",
    odom_frames: tuple[str, str] | None = None,
) -> BagScans:
    """Reads scans and odometry from a ROS1 ``.bag`` or a ROS2 bag folder.

    Args:
        path: the bag.
        scan_topic: LaserScan or PointCloud2 topic.
        odom_topic: nav_msgs/Odometry topic, or a tf2_msgs/TFMessage topic (``/tf``).
        sensor_offset: pose ``(x, y, yaw)`` of the sensor in the odometry child frame.
        xyz: keep z: scans ``(n_i, 3)``.
        base_frame: read the mounting from ``tf_topic`` instead: the static chain from this
            frame (the odometry's child frame, e.g. ``base_link``) to the scans' frame.
        tf_topic: the static-transform topic.
        odom_frames: ``(parent, child)`` of the odometry transforms when ``odom_topic``
            carries TFMessages (default ``("odom", base_frame or "base_link")``).

    Raises:
        DataError: unreadable bag, a missing topic or a topic of the wrong type (the topics
            present are listed), both ``sensor_offset`` and ``base_frame``, a ``/tf_static``
            without the frames needed (the frames present are listed), a ``/tf`` without
            the odometry transform (the transforms present are listed), a degenerate
            odometry quaternion, scans in millimetres, no scan within the odometry's span.

    Warns:
        DataWarning: non-unit odometry quaternions (normalised), scans outside the
            odometry's time span (left out).
    """
    path = Path(path)
    if base_frame is not None and np.any(np.asarray(sensor_offset, float) != 0):
        raise DataError(
            f"{path}: give the sensor mounting either as sensor_offset {tuple(sensor_offset)} "
            f"or from {tf_topic} (base_frame={base_frame!r}), not both"
        )
    reader = open_bag(path)
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        listing = ", ".join(f"{t} ({ty})" for t, ty in sorted(topics.items())) or "none"
        need = [(scan_topic, _SCAN_TYPES), (odom_topic, _ODOM_TYPES)]
        if base_frame is not None:
            need.append((tf_topic, ("tf2_msgs/msg/TFMessage",)))
        for topic, ok_types in need:
            if topic not in topics:
                raise DataError(f"{path}: no topic {topic!r}; topics present: {listing}")
            if topics[topic] not in ok_types:
                want = " or ".join(ok_types)
                raise DataError(f"{path}: topic {topic!r} carries {topics[topic]}, expected {want}")
        wanted = {t for t, _ in need}
        conns = [c for c in reader.connections if c.topic in wanted]
        s_t, scans, tf_msgs = [], [], []
        odo = _Odometry(odom_frames or ("odom", base_frame or "base_link"))
        frame, dropped = "", 0
        where = f"{path} {scan_topic}"
        for con, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, con.msgtype)
            if con.topic == odom_topic:
                odo.add(m)
            if con.topic == tf_topic:
                tf_msgs.append(m)
            if con.topic == scan_topic:
                s_t.append(_stamp(m))
                frame = frame or m.header.frame_id
                if con.msgtype.endswith("LaserScan"):
                    scans.append(laserscan_points(m, xyz))
                else:
                    pts, nd = pointcloud2_points(m, where, xyz)
                    scans.append(pts)
                    dropped += nd
    finally:
        reader.close()
    o_t, o_p = odo.poses(f"{path} {odom_topic}")
    check_some_points(scans, where)
    check_metres(scans, [f"{where} scan at t={t:.9f}" for t in s_t], str(path))
    mount = None
    if base_frame is not None:
        edges = static_edges(tf_msgs, f"{path} {tf_topic}")
        mount = transform_between(edges, base_frame, frame, f"{path} {tf_topic}")
        sensor_offset = planar_pose(mount)
    return _pair(
        f"{path} {odom_topic}",
        np.asarray(s_t),
        scans,
        o_t,
        o_p,
        sensor_offset,
        dict(dropped=dropped, frame_id=str(frame).lstrip("/"), mount=mount),
    )


def _first_of_each(t: np.ndarray) -> tuple[np.ndarray, int]:
    """Indices sorting ``t`` with repeated stamps removed (the first message wins)."""
    order = np.argsort(t, kind="stable")
    keep = np.unique(t[order], return_index=True)[1]
    return order[keep], len(t) - len(keep)


def _pair(where, s_t, scans, o_t, o_p, offset, extra) -> BagScans:
    """Scans with the odometry at their stamps (``timesync.odometry_at``), in stamp order;
    messages repeating a stamp are left out (the first wins: bags record in arrival order)."""
    o_idx, o_dup = _first_of_each(o_t)
    o_t, o_p = o_t[o_idx], o_p[o_idx]
    if len(o_t) == 0:
        raise DataError(f"{where}: no odometry messages")
    s_idx, s_dup = _first_of_each(s_t)
    s_t = s_t[s_idx]
    scans = [scans[i] for i in s_idx]
    inside, pose = odometry_at(o_t, o_p, s_t, where)
    t = s_t[inside]
    pose = sensor_poses(pose, offset)
    return BagScans(
        t,
        [scans[i] for i in np.flatnonzero(inside)],
        pose,
        int(np.count_nonzero(~inside)),
        o_t,
        o_p,
        duplicates=s_dup,
        odom_duplicates=o_dup,
        **extra,
    )


def read_tf_static(path, topic: str = "/tf_static") -> dict[tuple[str, str], np.ndarray]:
    """All static transforms of a bag, as ``static_edges``.

    Raises:
        DataError: unreadable bag, or no ``topic`` (the topics present are listed).
    """
    path = Path(path)
    reader = open_bag(path)
    try:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            listing = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
            raise DataError(f"{path}: no topic {topic!r}; topics present: {listing}")
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
    finally:
        reader.close()
    return static_edges(msgs, f"{path} {topic}")
