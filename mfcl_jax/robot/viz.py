"""``mfcl localize --viz out.mcap``: a run as an MCAP file that Foxglove opens as it is.

MCAP is the container of ROS 2 bags and Foxglove's native format; the messages are JSON with
Foxglove's well-known schemas, so the 3-D, Log, Plot and Raw Messages panels show them
without an extension. Everything is in one frame, ``plan`` (the floor plan's file frame:
plan = local + ``Floorplan.offset``), and on one timeline: a message's log time is its
window's time ``t`` (the plan's: the start).

Topics (one message per window on each, except the plan):

* ``/mfcl/plan`` (``foxglove.SceneUpdate``, once): walls, room outlines, doors, room names.
* ``/mfcl/scan`` (``foxglove.PointCloud``): the window's submap points at the robot's pose
  ``T* X_k`` when COMMIT (empty otherwise, so that a withdrawn commit shows nothing).
* ``/mfcl/pose`` (``foxglove.PosesInFrame``): the committed robot pose (or none).
* ``/mfcl/path`` (``foxglove.PosesInFrame``): the robot's path so far, every window of the
  current odometry segment placed by the current commit (empty without a commit).
* ``/mfcl/alternatives`` (``foxglove.PosesInFrame``): AMBIGUOUS: the robot's pose under the
  best placement and the strongest competitor (empty otherwise).
* ``/mfcl/state`` (``foxglove.Log``): the status line (state, reason, B1, B2, margin).
* ``/mfcl/decision`` (``mfcl.Decision``): the decisions-file record (plot B1, B2, margin).

The file is built in memory and written atomically by ``close`` (``io.atomic``): a reader
never sees half a file, an interrupted run leaves none. Plain host code (NumPy, no JAX).
"""

from __future__ import annotations

import base64
import io
import json
import math
from pathlib import Path

import numpy as np

from mfcl_jax.io.atomic import atomic_write
from mfcl_jax.io.errors import DataError
from mfcl_jax.robot.status import status_line
from mfcl_jax.robot.viz_messages import line_list, pose_msg, poses, ring_segments, stamp_of
from mfcl_jax.robot.viz_schemas import SCHEMAS

__all__ = ["FRAME", "TOPICS", "SCHEMAS", "VizWriter"]

FRAME = "plan"

TOPICS = {
    "/mfcl/plan": "foxglove.SceneUpdate",
    "/mfcl/scan": "foxglove.PointCloud",
    "/mfcl/pose": "foxglove.PosesInFrame",
    "/mfcl/path": "foxglove.PosesInFrame",
    "/mfcl/alternatives": "foxglove.PosesInFrame",
    "/mfcl/state": "foxglove.Log",
    "/mfcl/decision": "mfcl.Decision",
}
_LEVEL = {"COMMIT": 2, "DEFER": 2, "AMBIGUOUS": 3}  # foxglove.LogLevel INFO, WARNING


def _xyyaw(p: dict) -> tuple[float, float, float]:
    return float(p["x"]), float(p["y"]), math.radians(float(p["yaw_deg"]))


def _place(P, X, Xs) -> np.ndarray:
    """``P X^-1 Xs``: the poses ``Xs (n, 3)`` moved rigidly so that ``X`` lands on ``P``."""
    Xs = np.asarray(Xs, np.float64).reshape(-1, 3)
    rot = P[2] - X[2]
    c, s = math.cos(rot), math.sin(rot)
    dx, dy = Xs[:, 0] - X[0], Xs[:, 1] - X[1]
    return np.stack([P[0] + c * dx - s * dy, P[1] + s * dx + c * dy, Xs[:, 2] + rot], -1)


class VizWriter:
    """Collects a run window by window and writes it as one MCAP file.

    Args:
        path: the ``.mcap`` file to write (checked by the caller with ``io.check_output``),
            or None: no file (``live`` only).
        floorplan: the run's ``Floorplan``; drawn once, at the start.
        start: time (s) of the plan message; default the first window's time.
        live: also send every message as it is made to ``live.put(topic, schema, log_ns,
            json_bytes)`` (``robot.viz_live.FoxgloveLive``: the same content over
            Foxglove's WebSocket protocol).

    Raises:
        DataError: a ``start`` that cannot be an MCAP log time (negative, NaN).

    Example::

        viz = VizWriter("run.mcap", fp)
        for r in Localizer(fp).run(seq):
            viz.add(r, r.record(fp.offset))
        viz.close()
    """

    def __init__(self, path, floorplan, start: float | None = None, live=None):
        from mcap.writer import Writer

        self.path = None if path is None else Path(path)
        self.floorplan, self._live = floorplan, live
        self._offset = np.asarray(floorplan.offset, np.float64)
        self._start = None if start is None else float(start)
        if start is not None:
            self._ns(self._start, "the first scan")
        self._buf = io.BytesIO()
        self._writer = Writer(self._buf)
        self._writer.start(profile="", library="mfcl_jax")
        schema = {
            name: self._writer.register_schema(name, "jsonschema", json.dumps(s).encode())
            for name, s in SCHEMAS.items()
        }
        self._channels = {
            topic: self._writer.register_channel(topic, "json", schema[name])
            for topic, name in TOPICS.items()
        }
        ox, oy = (float(v) for v in self._offset)
        self._writer.add_metadata(
            "mfcl",
            {
                "floorplan": str(floorplan.name),
                "source": str(floorplan.source),
                "frame": FRAME,
                "offset": f"{ox!r},{oy!r}",
            },
        )
        self._history: list[tuple[int, np.ndarray]] = []  # (segment, X) of every window
        self._plan_written = False
        self._closed = False
        self.n_windows = 0

    def _ns(self, t: float, what: str) -> int:
        if not (math.isfinite(t) and t >= 0):
            where = self.path or "viz"
            raise DataError(
                f"{where}: {what} is at t={t} s; MCAP log times must be finite and >= 0 s"
            )
        return round(t * 1e9)

    def _put(self, topic: str, ns: int, msg: dict) -> None:
        data = json.dumps(msg, separators=(",", ":"), allow_nan=False).encode()
        if self.path is not None:
            self._writer.add_message(self._channels[topic], ns, data, ns)
        if self._live is not None:
            self._live.put(topic, TOPICS[topic], ns, data)

    def _plan(self, ns: int) -> None:
        fp, off = self.floorplan, self._offset
        rooms = ring_segments([r.polygon for r in fp.rooms]) if fp.rooms else np.zeros((0, 2, 2))
        doors = np.asarray([np.asarray(d.segment, np.float64) for d in fp.doors]).reshape(-1, 2, 2)
        texts = []
        for r in fp.rooms:
            p = r.polygon.representative_point()
            texts.append(
                {
                    "pose": pose_msg(p.x + off[0], p.y + off[1]),
                    "billboard": True,
                    "font_size": 12.0,
                    "scale_invariant": True,
                    "color": {"r": 1.0, "g": 1.0, "b": 1.0, "a": 0.8},
                    "text": r.name,
                }
            )
        entity = {
            "timestamp": stamp_of(ns),
            "frame_id": FRAME,
            "id": "floorplan",
            "lifetime": {"sec": 0, "nsec": 0},
            "frame_locked": False,
            "metadata": [{"key": "name", "value": str(fp.name)}],
            **{kind: [] for kind in ("arrows", "cubes", "spheres", "cylinders", "triangles")},
            "models": [],
            "texts": texts,
            "lines": [
                line_list(fp.wall_faces + off, (0.9, 0.9, 0.9, 1.0), 2.0),
                line_list(rooms + off, (0.3, 0.6, 1.0, 0.6), 1.0),
                line_list(doors + off, (1.0, 0.2, 0.2, 1.0), 3.0),
            ],
        }
        self._put("/mfcl/plan", ns, {"deletions": [], "entities": [entity]})

    def _drawn(self, p: dict, storey) -> dict:
        """A pose of the record (a storey's frame where the plan stacks several storeys,
        ``floorplan.storeys``) where the drawn plan shows it."""
        st = self.floorplan.storeys
        if st is None or storey is None:
            return p
        from mfcl_jax.se2 import compose_host  # only for a plan of several storeys

        ox, oy = (float(v) for v in self._offset)
        local = (float(p["x"]) - ox, float(p["y"]) - oy, math.radians(float(p["yaw_deg"])))
        x, y, yaw = compose_host(st.place[st.names.index(storey)], local)
        return {"x": float(x) + ox, "y": float(y) + oy, "yaw_deg": math.degrees(float(yaw))}

    def add(self, result, record: dict) -> None:
        """Adds one window.

        Args:
            result: its ``WindowResult`` (``k, t, X, segment, points``: the submap ``(n, 2)``
                in the window's frame, or None).
            record: its decisions-file record (``result.record(floorplan.offset)``).

        Raises:
            DataError: a window time that cannot be an MCAP log time (negative, NaN).
        """
        if self._closed:
            raise RuntimeError(f"{self.path}: the viz file is already closed")
        k, t = record["k"], float(record["t"])
        ns = self._ns(t, f"window k={k}")
        if not self._plan_written:
            start = t if self._start is None else min(self._start, t)
            self._plan(self._ns(start, "the start"))
            self._plan_written = True
        seg, X = int(getattr(result, "segment", 0)), np.asarray(result.X, np.float64)
        self._history.append((seg, X))
        pose = record.get("pose") if record["state"] == "COMMIT" else None
        if pose is not None:
            pose = self._drawn(pose, record.get("storey"))
        stamp, cloud = stamp_of(ns), np.zeros((0, 2), "<f4")
        path = np.zeros((0, 3))
        if pose is not None:
            P = np.asarray(_xyyaw(pose))
            if result.points is not None:
                cloud = np.asarray(result.points, "<f4")[:, :2]
            # Every window of this odometry segment through the same anchor T* = P X^-1.
            path = _place(P, X, [x for s, x in self._history if s == seg])
        self._put(
            "/mfcl/scan",
            ns,
            {
                "timestamp": stamp,
                "frame_id": FRAME,
                "pose": pose_msg(*(_xyyaw(pose) if pose is not None else (0.0, 0.0, 0.0))),
                "point_stride": 8,
                "fields": [
                    {"name": "x", "offset": 0, "type": 7},
                    {"name": "y", "offset": 4, "type": 7},
                ],
                "data": base64.b64encode(np.ascontiguousarray(cloud).tobytes()).decode("ascii"),
            },
        )
        one = [] if pose is None else [_xyyaw(pose)]
        alts = [_xyyaw(self._drawn(a, a.get("storey")))
                for a in (record.get("alternatives") or [])]  # fmt: skip
        for topic, rows in (
            ("/mfcl/pose", one),
            ("/mfcl/path", path),
            ("/mfcl/alternatives", alts),
        ):
            self._put(topic, ns, {"timestamp": stamp, "frame_id": FRAME, "poses": poses(rows)})
        self._put(
            "/mfcl/state",
            ns,
            {
                "timestamp": stamp,
                "level": _LEVEL.get(record["state"], 0),
                "message": status_line(record),
                "name": "mfcl",
                "file": "",
                "line": 0,
            },
        )
        self._put("/mfcl/decision", ns, record)
        self.n_windows += 1

    def close(self) -> Path:
        """Finishes the file and writes it atomically; returns its path.

        Raises:
            DataError: the file cannot be written (``io.atomic.atomic_write``).
        """
        if self._closed:
            raise RuntimeError(f"{self.path}: the viz file is already closed")
        if not self._plan_written:  # no window: the plan alone, at the start (or at 0)
            self._plan(self._ns(self._start or 0.0, "the start"))
            self._plan_written = True
        self._writer.finish()
        self._closed = True
        if self.path is None:
            return None
        return atomic_write(self.path, self._buf.getvalue())

    def discard(self) -> None:
        """Drops what was collected; nothing is written."""
        self._closed = True
        self._buf = io.BytesIO()
