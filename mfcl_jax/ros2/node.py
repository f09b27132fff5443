"""``mfcl ros2``: the layer as a live ROS 2 node (DDS), next to nav2.

In: the robot's scans, odometry and ``/tf_static`` (``ros2.feed``). Every window goes
through the same ``Localizer.follow`` as ``mfcl localize --follow`` (one jitted step; the
decisions are those of a recording of the same messages). Out:

- ``/mfcl/status`` (``std_msgs/String``, reliable): one JSON object per message. Per window,
  the decisions-file line (``docs/status.md``: ``k, segment, t, state, anchor, ..., pose``).
  Between windows, events: ``{"event": "start" | "silent" | "restart" | "stop" | "warning",
  "state", "reason", "k", "segment", "t"}``; ``"silent"`` (a topic without messages for
  ``--silence`` s) and ``"start"`` carry ``state: "DEFER"``: the node says it does not
  know, it never guesses.
- ``/initialpose`` (``geometry_msgs/PoseWithCovarianceStamped``, frame ``map`` = the floor
  plan's frame, reliable and latched): the robot's base pose at the committing window's
  last scan, with the covariance of the fit there (``robot.covariance``); published at the
  first COMMIT of each odometry segment (after a restart, a new commit publishes again).
  What nav2's AMCL listens to.
- ``/tf`` ``map -> odom`` (``--publish-tf``): the committed anchor, stamped with each new
  scan (plus ``TF_AHEAD_S``, as AMCL does), for stacks without AMCL.

Ground truth never enters; nothing here reads a file but the floor plan.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field, replace

import numpy as np

from mfcl_jax.ros2 import dds
from mfcl_jax.ros2 import messages as M
from mfcl_jax.ros2.feed import TopicFeed
from mfcl_jax.ros2.topics import FeedParams

__all__ = ["NodeParams", "Node", "TF_AHEAD_S"]

TF_AHEAD_S = 0.5  # map -> odom is stamped this far past the newest scan (AMCL's tolerance)


@dataclass(frozen=True)
class NodeParams:
    """Topics and frames of the node (ROS 2's usual names by default)."""

    feed: FeedParams = field(default_factory=FeedParams)
    pose_topic: str = "/initialpose"
    status_topic: str = "/mfcl/status"
    map_frame: str = "map"
    publish_tf: bool = False


class Node:
    """The live node. Its topics open at construction (a ``start`` event goes out at once,
    and messages that arrive while the plan loads and the step compiles wait in the
    readers); ``run`` decides until a signal (``KeyboardInterrupt``) stops it.

    Args:
        bus: a ``dds.Bus``.
        params: ``NodeParams``.
        log: a line for a person (stderr).
    """

    def __init__(self, bus, params: NodeParams, log=None):
        self.params = params
        self.floorplan = self.localize = None
        self.log = log or (lambda text: print(text, file=sys.stderr, flush=True))
        self._status = bus.writer(params.status_topic, M.String, dds.RELIABLE)
        self._pose = bus.writer(params.pose_topic, M.PoseWithCovarianceStamped, dds.LATCHED)
        self._tf = bus.writer("/tf", M.TFMessage, dds.RELIABLE) if params.publish_tf else None
        self.records: list[dict] = []
        self.poses: list[dict] = []  # every /initialpose published (x, y, yaw, cov, t)
        self._k, self._segment, self._t = 0, 0, None
        self._anchor = None  # the committed anchor (plan frame) of the current segment
        self._published_segment = None
        self.feed = TopicFeed(bus, params.feed, self.event)
        self._rasters = None
        self.on_window = None  # callback(result, record): --viz, tests
        self.event("start", "starting: loading the floor plan and the layer", "DEFER")

    # ------------------------------------------------------------ publishing
    def status(self, obj: dict) -> None:
        self._status.write(M.String(data=json.dumps(obj, allow_nan=False)))

    def event(self, event: str, reason: str, state: str | None = None) -> None:
        """An event on the status topic (``silent`` is always a DEFER), said on stderr too
        for ``warning``, ``silent`` and ``restart``."""
        if event == "silent":
            state = "DEFER"
        if event in ("warning", "silent", "restart"):
            self.log(f"mfcl: {event}: {reason}")
        self.status({"event": event, "state": state, "reason": reason, "k": self._k,
                     "segment": self._segment, "t": self._t})  # fmt: skip

    def _publish_pose(self, result, rec: dict) -> None:
        from mfcl_jax.io.tf_static import sensor_poses
        from mfcl_jax.robot.covariance import pose_covariance, to_base
        from mfcl_jax.se2 import inverse_host

        p = rec["pose"]
        ox, oy = self.floorplan.offset
        sensor = np.array([p["x"] - ox, p["y"] - oy, math.radians(p["yaw_deg"])])
        mount = self.feed.mount(self.feed.frame_id) or (0.0, 0.0, 0.0)
        base = sensor_poses(sensor[None], inverse_host(np.asarray(mount)))[0]
        cov = to_base(pose_covariance(self._rasters, result.points, sensor), sensor, base)
        c6 = np.zeros((6, 6))
        idx = (0, 1, 5)
        for i in range(3):
            for j in range(3):
                c6[idx[i], idx[j]] = cov[i, j]
        bx, by = float(base[0]) + ox, float(base[1]) + oy
        msg = M.PoseWithCovarianceStamped(
            header=M.Header(stamp=M.time_msg(result.t), frame_id=self.params.map_frame),
            pose=M.PoseWithCovariance(
                pose=M.Pose(position=M.Point(x=bx, y=by),
                            orientation=M.yaw_quaternion(float(base[2]))),
                covariance=[float(v) for v in c6.ravel()],
            ),
        )  # fmt: skip
        self._pose.write(msg)
        self.poses.append(
            {
                "t": result.t,
                "x": bx,
                "y": by,
                "yaw": float(base[2]),
                "cov": cov.tolist(),
                "k": rec["k"],
                "segment": rec["segment"],
            }
        )
        self.log(f"mfcl: {self.params.pose_topic}: x={bx:.2f} m, y={by:.2f} m, "
                 f"yaw={math.degrees(base[2]):.1f} deg at t={result.t:.3f} "
                 f"(sd {math.sqrt(cov[0, 0]):.3f} m, {math.sqrt(cov[1, 1]):.3f} m, "
                 f"{math.degrees(math.sqrt(cov[2, 2])):.2f} deg)")  # fmt: skip

    def _publish_tf(self, t: float) -> None:
        if self._tf is None or self._anchor is None:
            return
        x, y, yaw = self._anchor
        odom = self.params.feed.odom_frames[0]
        tr = M.Transform(translation=M.Vector3(x=x, y=y), rotation=M.yaw_quaternion(yaw))
        ts = M.TransformStamped(header=M.Header(stamp=M.time_msg(t + TF_AHEAD_S),
                                                frame_id=self.params.map_frame),
                                child_frame_id=odom, transform=tr)  # fmt: skip
        self._tf.write(M.TFMessage([ts]))

    # ------------------------------------------------------------ running
    def _window(self, result) -> None:
        offset = self.floorplan.offset
        rec = result.record(offset)
        self.records.append(rec)
        self._k, self._t = result.k, result.t
        from mfcl_jax.io.decisions import decision_line

        self._status.write(M.String(data=decision_line(rec)))
        if rec["state"] == "COMMIT":
            a = rec["anchor"]
            self._anchor = (a["x"], a["y"], math.radians(a["yaw_deg"]))
            self._publish_tf(self._t)
            if self._published_segment != result.segment:
                self._published_segment = result.segment
                self._publish_pose(result, rec)
        if self.on_window is not None:
            self.on_window(result, rec)

    def _prefixes(self):
        """The feed's prefixes, with ``map -> odom`` sent on each new scan."""
        for seq in self.feed.prefixes():
            self._t = float(seq.times[-1])
            self._publish_tf(self._t)
            yield seq

    def run(self, loc) -> None:
        """Decides window after window (``loc``: a ``Localizer`` on the plan) until a signal
        raises ``KeyboardInterrupt``; a time jump starts a new segment."""
        self.floorplan, self.localize = loc.floorplan, loc.params
        self._rasters = self.floorplan.rasterize(res=0.05)  # the covariance's distance field
        why = self.feed.waiting() or "scans arriving"
        self.event("start", f"ready, {why}; a window needs {loc.params.d_s:g} m of travel",
                    "DEFER")  # fmt: skip
        prepare = True
        while True:
            base_k, base_seg = self._k, self._segment
            for r in loc.follow(self._prefixes(), prepare=prepare):
                seg = base_seg + r.segment
                if seg != self._segment:
                    self._anchor = None
                self._segment = seg
                self._window(replace(r, k=base_k + r.k, segment=seg))
                self.feed.release(r.first)
            prepare = False
            self._segment += 1
            self._anchor = None
            self.event("restart", f"time went back to t={self.feed.newest or 0.0:.3f} s: the "
                       f"layer starts over (segment {self._segment})")  # fmt: skip
            self.feed.next_segment()
