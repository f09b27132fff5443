"""A recording played onto ROS 2 topics, as a robot (or ``ros2 bag play``) publishes it.

Used by ``mfcl play`` (try the node without a robot), by the tests (a real DDS participant in
another process than the node) and by ``benchmarks/ros2_node.py``. Scans go out as
``sensor_msgs/LaserScan`` (one beam per ``2 pi / n_beams`` from angle 0: the simulator's ring,
so the points come back exactly) or ``PointCloud2`` (x, y, z float32), the odometry as
``nav_msgs/Odometry`` or as ``/tf`` transforms ``odom -> base_link``, and the LiDAR mounting
once on ``/tf_static`` (latched). Messages leave in stamp order at ``rate`` times real time.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from mfcl_jax.ros2 import dds
from mfcl_jax.ros2 import messages as M

__all__ = [
    "PlayParams", "Player", "laserscan", "pointcloud2", "odometry_msg", "from_rosbags",
    "bag_messages",
]  # fmt: skip


def laserscan(t: float, points, frame: str, n_beams: int = 720, range_max: float = 40.0):
    """A ``LaserScan`` holding planar ``points (n, 2)`` (sensor frame) on a ring of
    ``n_beams`` beams from angle 0; beams without a point read +inf (no return)."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    inc = 2 * math.pi / n_beams
    ranges = np.full(n_beams, np.inf, np.float32)
    k = np.round(np.arctan2(pts[:, 1], pts[:, 0]) / inc).astype(int) % n_beams
    ranges[k] = np.hypot(pts[:, 0], pts[:, 1])
    return M.LaserScan(
        header=M.Header(stamp=M.time_msg(t), frame_id=frame), angle_min=0.0,
        angle_max=float(inc * (n_beams - 1)), angle_increment=float(inc), range_min=0.05,
        range_max=float(range_max), ranges=ranges.tolist(),
    )  # fmt: skip


def pointcloud2(t: float, points, frame: str):
    """A ``PointCloud2`` of ``points (n, 2 or 3)`` (x, y, z float32, z = 0 for planar)."""
    pts = np.asarray(points, np.float32)
    if pts.shape[1] == 2:
        pts = np.concatenate([pts, np.zeros((len(pts), 1), np.float32)], 1)
    fields = [M.PointField(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xyz")]
    return M.PointCloud2(
        header=M.Header(stamp=M.time_msg(t), frame_id=frame), height=1, width=len(pts),
        fields=fields, is_bigendian=False, point_step=12, row_step=12 * len(pts),
        data=list(pts.astype("<f4").tobytes()), is_dense=True,
    )  # fmt: skip


def odometry_msg(t: float, pose, frames=("odom", "base_link")):
    x, y, yaw = (float(v) for v in pose)
    p = M.Pose(position=M.Point(x=x, y=y), orientation=M.yaw_quaternion(yaw))
    return M.Odometry(header=M.Header(stamp=M.time_msg(t), frame_id=frames[0]),
                      child_frame_id=frames[1], pose=M.PoseWithCovariance(pose=p))  # fmt: skip


def _transform(t: float, parent: str, child: str, pose) -> M.TransformStamped:
    x, y, yaw = (float(v) for v in pose)
    tr = M.Transform(translation=M.Vector3(x=x, y=y), rotation=M.yaw_quaternion(yaw))
    return M.TransformStamped(header=M.Header(stamp=M.time_msg(t), frame_id=parent),
                              child_frame_id=child, transform=tr)  # fmt: skip


@dataclass(frozen=True)
class PlayParams:
    """Topics and frames of the played recording (the node's defaults); ``reliable``: scans
    and odometry written reliably, keep all (``dds.STREAM``), for a node run with
    ``--reliable`` (nothing lost on a loaded machine), instead of as a LiDAR driver does."""

    scan_topic: str = "/scan"
    cloud: bool = False
    odom_topic: str = "/odom"  # or "/tf"
    frames: tuple[str, str] = ("odom", "base_link")
    scan_frame: str = "laser"
    rate: float = 1.0
    reliable: bool = False


class Player:
    """Publishes recordings onto one ``dds.Bus``.

    Args:
        bus: the ``dds.Bus`` (its domain is the node's).
        params: ``PlayParams``.
    """

    def __init__(self, bus, params: PlayParams | None = None):
        self.params = p = params or PlayParams()
        scan_qos, odom_qos = (dds.STREAM, dds.STREAM) if p.reliable else (dds.SENSOR, dds.RELIABLE)
        self._scan = bus.writer(p.scan_topic, M.PointCloud2 if p.cloud else M.LaserScan,
                                scan_qos)  # fmt: skip
        tf = p.odom_topic.strip("/") == "tf"
        self._odom = bus.writer(p.odom_topic, M.TFMessage if tf else M.Odometry, odom_qos)
        self._tf_static = bus.writer("/tf_static", M.TFMessage, dds.LATCHED)
        self.sent = 0

    def wait_for_readers(self, timeout: float = 10.0) -> bool:
        """Waits until the scan and odometry topics each have a reader (DDS discovery takes a
        moment: messages written before it are lost for best-effort readers); False when
        ``timeout`` s passed first."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self._scan.get_matched_subscriptions() and self._odom.get_matched_subscriptions():
                return True
            time.sleep(0.02)
        return False

    def mount(self, pose) -> None:
        """Publishes the LiDAR's planar pose on the base on ``/tf_static`` (latched)."""
        p = self.params
        self._tf_static.write(M.TFMessage([_transform(0.0, p.frames[1], p.scan_frame, pose)]))

    def _odom_msg(self, t, pose):
        p = self.params
        if p.odom_topic.strip("/") == "tf":
            return M.TFMessage([_transform(t, *p.frames, pose)])
        return odometry_msg(t, pose, p.frames)

    def play(self, scan_times, scans, odom_times, odom_poses, offset: float = 0.0,
             stop=None) -> None:  # fmt: skip
        """Publishes scans and base odometry in stamp order (stamps ``+ offset``), paced at
        ``rate`` times real time from the first stamp; ``stop()`` true ends it early."""
        p = self.params
        events = [(float(t), 1, i) for i, t in enumerate(scan_times)]
        events += [(float(t), 0, i) for i, t in enumerate(odom_times)]
        events.sort()
        if not events:
            return
        t0, w0 = events[0][0], time.monotonic()
        for t, kind, i in events:
            if stop is not None and stop():
                return
            wait = w0 + (t - t0) / p.rate - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            if kind == 0:
                self._odom.write(self._odom_msg(t + offset, odom_poses[i]))
            elif p.cloud:
                self._scan.write(pointcloud2(t + offset, scans[i], p.scan_frame))
            else:
                self._scan.write(laserscan(t + offset, scans[i], p.scan_frame))
            self.sent += 1

    def play_messages(self, messages, stop=None) -> None:
        """Publishes ``[(t, topic, sample)]`` (``bag_messages``) in order, paced at ``rate``
        times real time; the topics are the player's scan and odometry topics and
        ``/tf_static``."""
        writers = {self.params.scan_topic: self._scan, self.params.odom_topic: self._odom,
                   "/tf_static": self._tf_static}  # fmt: skip
        w0, t0 = time.monotonic(), None
        for t, topic, msg in messages:
            if stop is not None and stop():
                return
            if topic != "/tf_static":
                t0 = t if t0 is None else t0
                wait = w0 + (t - t0) / self.params.rate - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            writers[topic].write(msg)
            self.sent += 1


def _header(h) -> M.Header:
    return M.Header(stamp=M.Time(int(h.stamp.sec), int(h.stamp.nanosec)), frame_id=h.frame_id)


def _vector(v) -> M.Vector3:
    return M.Vector3(float(v.x), float(v.y), float(v.z))


def _quat(q) -> M.Quaternion:
    return M.Quaternion(float(q.x), float(q.y), float(q.z), float(q.w))


def from_rosbags(msg, msgtype: str):
    """The DDS sample of a message deserialized by ``rosbags`` (ROS 1 or ROS 2 bag), for the
    types a robot's recording carries: LaserScan, PointCloud2, Odometry, TFMessage."""
    if msgtype == "sensor_msgs/msg/LaserScan":
        return M.LaserScan(_header(msg.header), float(msg.angle_min), float(msg.angle_max),
                           float(msg.angle_increment), float(msg.time_increment),
                           float(msg.scan_time), float(msg.range_min), float(msg.range_max),
                           np.asarray(msg.ranges, np.float32).tolist(),
                           np.asarray(msg.intensities, np.float32).tolist())  # fmt: skip
    if msgtype == "sensor_msgs/msg/PointCloud2":
        fields = [M.PointField(f.name, int(f.offset), int(f.datatype), int(f.count))
                  for f in msg.fields]  # fmt: skip
        return M.PointCloud2(_header(msg.header), int(msg.height), int(msg.width), fields,
                             bool(msg.is_bigendian), int(msg.point_step), int(msg.row_step),
                             bytes(msg.data), bool(msg.is_dense))  # fmt: skip
    if msgtype == "nav_msgs/msg/Odometry":
        p = msg.pose.pose
        pose = M.Pose(M.Point(float(p.position.x), float(p.position.y), float(p.position.z)),
                      _quat(p.orientation))  # fmt: skip
        return M.Odometry(_header(msg.header), msg.child_frame_id, M.PoseWithCovariance(pose))
    if msgtype == "tf2_msgs/msg/TFMessage":
        return M.TFMessage([M.TransformStamped(
            _header(ts.header), ts.child_frame_id,
            M.Transform(_vector(ts.transform.translation), _quat(ts.transform.rotation)))
            for ts in msg.transforms])  # fmt: skip
    raise ValueError(f"no DDS type for {msgtype}")


def bag_messages(path, topics=("/scan", "/odom", "/tf_static"), seconds: float | None = None):
    """``[(t, topic, sample)]`` of a bag's ``topics`` in time order (``t``: the bag's receive
    time, s), the first ``seconds`` of it; ``/tf_static`` messages first."""
    from mfcl_jax.io.bag import open_bag

    reader = open_bag(path)
    try:
        conns = [c for c in reader.connections if c.topic in topics]
        out, t0 = [], None
        for c, ns, raw in reader.messages(connections=conns):
            t = ns * 1e-9
            t0 = t if t0 is None else t0
            if seconds is not None and t - t0 > seconds and c.topic != "/tf_static":
                break
            out.append((t, c.topic, from_rosbags(reader.deserialize(raw, c.msgtype), c.msgtype)))
    finally:
        reader.close()
    out.sort(key=lambda e: (e[1] != "/tf_static", e[0]))
    return out
