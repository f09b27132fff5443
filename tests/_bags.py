"""Synthesized ROS messages and bags for the tests: PointCloud2 of real drivers' layouts
(raw bytes built with NumPy structured dtypes), odometry, /tf_static, ROS1 and ROS2 writers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

F32, U8, U16, U32 = 7, 2, 4, 6
_NP = {F32: "f4", U8: "u1", U16: "u2", U32: "u4"}

# (name, offset, datatype) and point_step of three drivers' clouds.
LIVOX = ([("x", 0, F32), ("y", 4, F32), ("z", 8, F32), ("intensity", 12, F32),
          ("tag", 16, U8), ("line", 17, U8)], 18)  # fmt: skip
VELODYNE = ([("x", 0, F32), ("y", 4, F32), ("z", 8, F32), ("intensity", 16, F32),
             ("ring", 20, U16), ("time", 24, F32)], 32)  # fmt: skip
OUSTER = ([("x", 0, F32), ("y", 4, F32), ("z", 8, F32), ("t", 16, U32),
           ("reflectivity", 20, U16), ("ring", 22, U16), ("ambient", 24, U16),
           ("range", 28, U32)], 48)  # fmt: skip


def store(ros1: bool = True):
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in ts.types:
        ts.register(
            get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
            )
        )
    return ts


def header(ts, t: float, frame: str):
    H = ts.types["std_msgs/msg/Header"]
    stamp = ts.types["builtin_interfaces/msg/Time"](sec=int(t), nanosec=int(round((t % 1) * 1e9)))
    if "seq" in H.__dataclass_fields__:
        return H(seq=0, stamp=stamp, frame_id=frame)
    return H(stamp=stamp, frame_id=frame)


def cloud_bytes(xyz, layout, bigendian=False, extra_row_bytes=0, height=1):
    """Raw PointCloud2 bytes ``(data, point_step, row_step)`` for points ``(n, 3)``."""
    fields, step = layout
    end = ">" if bigendian else "<"
    dt = np.dtype(
        {
            "names": [f for f, _, _ in fields],
            "formats": [end + _NP[d] for _, _, d in fields],
            "offsets": [o for _, o, _ in fields],
            "itemsize": step,
        }
    )
    xyz = np.asarray(xyz, float)
    rec = np.zeros(len(xyz), dt)
    for i, c in enumerate("xyz"):
        rec[c] = xyz[:, i]
    for f, _, d in fields[3:]:
        rec[f] = np.arange(len(xyz)) % 100 if d != F32 else 0.5
    width = len(xyz) // height
    rows = rec.tobytes()
    row_step = width * step + extra_row_bytes
    data = b"".join(
        rows[r * width * step : (r + 1) * width * step] + b"\xee" * extra_row_bytes
        for r in range(height)
    )
    return np.frombuffer(data, np.uint8).copy(), step, row_step


def pointcloud2(ts, t, xyz, layout, frame="lidar", bigendian=False, height=1, extra_row_bytes=0):
    data, step, row_step = cloud_bytes(xyz, layout, bigendian, extra_row_bytes, height)
    PF = ts.types["sensor_msgs/msg/PointField"]
    fields = [PF(name=n, offset=o, datatype=d, count=1) for n, o, d in layout[0]]
    return ts.types["sensor_msgs/msg/PointCloud2"](
        header=header(ts, t, frame),
        height=height,
        width=len(xyz) // height,
        fields=fields,
        is_bigendian=bigendian,
        point_step=step,
        row_step=row_step,
        data=data,
        is_dense=False,
    )


def odometry(ts, t, x, y, yaw, frame="odom", child="base_link", q_scale=1.0):
    """A nav_msgs/Odometry at ``(x, y, yaw)``; ``q_scale`` scales its quaternion (a bad
    driver's non-unit quaternion)."""
    T = ts.types
    pose = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=q_scale * math.sin(yaw / 2), w=q_scale * math.cos(yaw / 2)
        ),
    )
    zero3 = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    return T["nav_msgs/msg/Odometry"](
        header=header(ts, t, frame),
        child_frame_id=child,
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=zero3, angular=zero3),
            covariance=np.zeros(36),
        ),
    )


def tf_message(ts, edges, t=0.0):
    """A TFMessage from ``[(parent, child, (x, y, z), (qx, qy, qz, qw)), ...]`` stamped ``t``."""
    T = ts.types
    out = []
    for parent, child, tr, q in edges:
        out.append(
            T["geometry_msgs/msg/TransformStamped"](
                header=header(ts, t, parent),
                child_frame_id=child,
                transform=T["geometry_msgs/msg/Transform"](
                    translation=T["geometry_msgs/msg/Vector3"](x=tr[0], y=tr[1], z=tr[2]),
                    rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
                ),
            )
        )
    return T["tf2_msgs/msg/TFMessage"](transforms=out)


def write_bag(path: Path, ts, messages, ros1: bool = True) -> Path:
    """Writes ``[(topic, msgtype, t, msg), ...]`` as a ROS1 .bag or a ROS2 bag folder."""
    if ros1:
        from rosbags.rosbag1 import Writer

        writer, serialize = Writer(path), ts.serialize_ros1
    else:
        from rosbags.rosbag2 import Writer

        writer, serialize = Writer(path, version=9), ts.serialize_cdr
    with writer as w:
        conns = {}
        for topic, msgtype, t, msg in messages:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], int(t * 1e9), serialize(msg, msgtype))
    return path


def quat_yaw(yaw):
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
