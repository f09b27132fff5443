"""Static transforms (``/tf_static``, ``tf2_msgs/TFMessage``): the LiDAR mounting offset.

Each ``geometry_msgs/TransformStamped`` gives the pose of ``child_frame_id`` in
``header.frame_id`` (translation + unit quaternion ``x y z w``). ``transform_between``
chains them, forwards or inverted, from a parent frame (e.g. ``base_link``) to the scan's
frame, so a tree such as ``base_link -> lidar_mount -> os_sensor -> os_lidar`` gives the
sensor's pose in ``base_link`` as one 4x4 matrix. Frame names are compared without a
leading ``/`` (ROS1 bags often write ``/base_link``). Quaternions are checked as odometry's
are (``io.tum.unit_quaternions``: a non-unit one is normalised with a ``DataWarning``, a
degenerate one is a ``DataError``).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.tum import unit_quaternions
from mfcl_jax.se2 import wrap_host

__all__ = [
    "matrix_from_quaternion",
    "static_edges",
    "transform_between",
    "planar_pose",
    "xyz_rpy",
    "sensor_poses",
]


def _frame(name: str) -> str:
    return str(name).lstrip("/")


def matrix_from_quaternion(translation, quaternion) -> np.ndarray:
    """The 4x4 homogeneous transform of a translation ``(3,)`` and quaternion ``(x, y, z, w)``.

    Raises:
        DataError: a zero or non-finite quaternion.
    """
    t = np.asarray(translation, np.float64).reshape(3)
    q = np.asarray(quaternion, np.float64).reshape(4)
    norm = np.linalg.norm(q)
    if not (np.all(np.isfinite(t)) and np.isfinite(norm) and norm > 1e-9):
        raise DataError(f"transform with translation {t.tolist()} quaternion {q.tolist()}")
    x, y, z, w = q / norm
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, t
    return out


def static_edges(messages, where: str = "/tf_static") -> dict[tuple[str, str], np.ndarray]:
    """``{(parent, child): 4x4}`` from deserialized TFMessages (a later duplicate wins, as in
    tf2's static buffer)."""
    edges = {}
    for m in messages:
        for ts in m.transforms:
            tr, q = ts.transform.translation, ts.transform.rotation
            parent, child = _frame(ts.header.frame_id), _frame(ts.child_frame_id)
            unit_quaternions([(q.x, q.y, q.z, q.w)], [f"{where}: {parent} -> {child}"])
            try:
                edges[(parent, child)] = matrix_from_quaternion(
                    (tr.x, tr.y, tr.z), (q.x, q.y, q.z, q.w)
                )
            except DataError as e:
                raise DataError(f"{where}: {parent} -> {child}: bad {e}") from None
    return edges


def transform_between(edges, parent: str, child: str, where: str = "/tf_static") -> np.ndarray:
    """The pose ``(4, 4)`` of frame ``child`` in frame ``parent``, chaining static edges.

    Raises:
        DataError: no chain joins the two frames; the message lists the frames present.
    """
    parent, child = _frame(parent), _frame(child)
    graph: dict[str, list[tuple[str, np.ndarray]]] = {}
    for (a, b), T in edges.items():
        graph.setdefault(a, []).append((b, T))
        graph.setdefault(b, []).append((a, np.linalg.inv(T)))
    if parent == child:
        return np.eye(4)
    seen = {parent: np.eye(4)}
    todo = deque([parent])
    while todo:
        a = todo.popleft()
        for b, T in graph.get(a, ()):
            if b not in seen:
                seen[b] = seen[a] @ T
                if b == child:
                    return seen[b]
                todo.append(b)
    frames = ", ".join(sorted(graph)) or "none"
    raise DataError(
        f"{where}: no static transform joins {parent!r} to {child!r}; frames present: {frames}"
    )


def xyz_rpy(T) -> np.ndarray:
    """``(x, y, z, roll, pitch, yaw)`` of a 4x4 transform (rotation ``Rz(yaw) Ry(pitch)
    Rx(roll)``)."""
    T = np.asarray(T, np.float64)
    r = T[:3, :3]
    yaw = np.arctan2(r[1, 0], r[0, 0])
    pitch = np.arctan2(-r[2, 0], np.hypot(r[2, 1], r[2, 2]))
    roll = np.arctan2(r[2, 1], r[2, 2])
    return np.array([T[0, 3], T[1, 3], T[2, 3], roll, pitch, yaw])


def planar_pose(T) -> np.ndarray:
    """The planar part ``(x, y, yaw)`` of a 4x4 transform (z, roll and pitch dropped)."""
    x, y, _, _, _, yaw = xyz_rpy(T)
    return np.array([x, y, yaw])


def sensor_poses(base_poses, mounting) -> np.ndarray:
    """Sensor poses ``(N, 3)``: base poses ``(N, 3)`` composed with the planar mounting
    ``(x, y, yaw)`` of the sensor in the base frame (yaw wrapped to ``(-pi, pi]``)."""
    p = np.asarray(base_poses, np.float64).reshape(-1, 3)
    ox, oy, oth = (float(v) for v in mounting)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    yaw = p[:, 2] + oth
    return np.stack(
        [
            p[:, 0] + c * ox - s * oy,
            p[:, 1] + s * ox + c * oy,
            wrap_host(yaw),
        ],
        -1,
    )
