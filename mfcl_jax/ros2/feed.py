"""A robot's topics as a recording that grows: DDS samples in, ``ScanSequence`` prefixes out.

``TopicFeed`` reads the scan topic (``LaserScan``, or ``PointCloud2`` with ``cloud=True``), the
odometry (``nav_msgs/Odometry``, or ``/tf`` from ``odom_frames[0]`` to ``odom_frames[1]``) and,
unless the mounting is given, ``/tf_static`` (``base_frame`` to the scans' frame). Scans join in
stamp order, as ``robot.live.Follower`` joins a folder's files: once an odometry message at or
after their stamp arrives (the pose interpolated as the batch path does, ``io.timesync``),
composed with the mounting (the SENSOR pose in the odometry frame). 3-D clouds are cut by the
height band as they arrive (``sources.planar.PlanarStream``).

- a stamp older than its stream's newest by more than ``topics.JUMP_S`` starts a new epoch of
  that stream; once scans and odometry have both jumped, the segment ends (``prefixes``
  returns); a stamp at or a little before the newest is late, left out and counted;
- a scan older than its segment's first odometry is left out (counted);
- ``silence_s`` s of wall time without a message on a topic: ``notify("silent", reason)``;
- a message that cannot be read (a bad quaternion, a PointCloud2 without x): a warning naming
  the topic, the stamp and the value, the message left out (counted).

``release(j)`` drops the points before scan ``j``: memory stays bounded on a long run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.io.tf_static import sensor_poses
from mfcl_jax.io.timesync import TIME_TOL_S, interpolate_se2
from mfcl_jax.robot.signals import checkpoint
from mfcl_jax.ros2 import dds
from mfcl_jax.ros2.topics import FeedParams, Stream
from mfcl_jax.sources.planar import PlanarStream
from mfcl_jax.sources.sequence import ScanSequence

__all__ = ["TopicFeed"]

_EMPTY = np.zeros((0, 2))


class TopicFeed:
    """The robot's topics as ``ScanSequence`` prefixes, one segment at a time.

    Args:
        bus, params: a ``dds.Bus``; ``FeedParams``.
        notify: ``notify(event, reason)`` for ``"silent"`` and ``"warning"``.
        poll: the longest wait for a message (s) before the silence is checked again.
    """

    def __init__(self, bus, params: FeedParams, notify: Callable[[str, str], None],
                 poll: float = 0.1, clock=time.monotonic):  # fmt: skip
        from mfcl_jax.ros2 import messages as M

        self.params, self.notify, self.poll, self._clock = params, notify, poll, clock
        kind = M.PointCloud2 if params.cloud else M.LaserScan
        qos = dds.STREAM if params.reliable else dds.SENSOR
        self._scan_reader = bus.reader(params.scan_topic, kind, qos)
        odom_kind = M.TFMessage if params.odom_topic.strip("/") == "tf" else M.Odometry
        self._odom_reader = bus.reader(params.odom_topic, odom_kind, qos)
        self._tf_reader = None
        if params.mount is None:
            self._tf_reader = bus.reader(params.tf_static_topic, M.TFMessage, dds.LATCHED)
        self._wait = bus.waiter([self._scan_reader, self._odom_reader, self._tf_reader])
        self._edges: dict = {}
        self._mounts: dict = {}  # scan frame -> planar mount
        self.frame_id = ""
        self._scans, self._odom = Stream(), Stream()
        self._segment = 0  # epoch of both streams that the current segment reads
        self._odom_t: dict[int, list] = {}  # epoch -> stamps / base poses
        self._odom_p: dict[int, list] = {}
        self._queue: dict[int, list] = {}  # epoch -> [(t, frame, points)] not joined yet
        self._planar = PlanarStream(params.planar)
        self.counts = dict.fromkeys(("early", "late", "bad", "stale"), 0)
        self._start = clock()
        self._silent_since: dict[str, float] = {}
        self._reset_segment()

    # ---------------------------------------------------------------- reading
    def _reset_segment(self) -> None:
        self._times: list[float] = []
        self._poses: list[np.ndarray] = []
        self._planar_scans: list[np.ndarray] = []
        self._released = 0

    def _warn(self, text: str) -> None:
        self.counts["bad"] += 1
        self.notify("warning", text)

    def _read_tf_static(self) -> None:
        from mfcl_jax.io.tf_static import static_edges

        msgs = dds.take(self._tf_reader)
        if msgs:
            try:
                self._edges |= static_edges(msgs, self.params.tf_static_topic)
            except DataError as e:
                self._warn(str(e))
            self._mounts.clear()

    def mount(self, frame: str):
        """The planar mount of the scans of ``frame``, or None while ``/tf_static`` lacks it."""
        if self.params.mount is not None:
            return self.params.mount
        if frame not in self._mounts:
            from mfcl_jax.io.tf_static import planar_pose, transform_between

            base = self.params.base_frame.lstrip("/")
            if frame.lstrip("/") == base:
                self._mounts[frame] = (0.0, 0.0, 0.0)
            else:
                try:
                    T = transform_between(self._edges, base, frame, self.params.tf_static_topic)
                except DataError:
                    return None
                self._mounts[frame] = tuple(float(v) for v in planar_pose(T))
        return self._mounts[frame]

    def _read_odometry(self, now: float) -> bool:
        from mfcl_jax.io.tum import yaw_from_quat
        from mfcl_jax.ros2.messages import stamp_of

        where = self.params.odom_topic
        rows = []
        for m in dds.take(self._odom_reader):
            if hasattr(m, "transforms"):
                want = tuple(f.lstrip("/") for f in self.params.odom_frames)
                for ts in m.transforms:
                    pair = (ts.header.frame_id.lstrip("/"), ts.child_frame_id.lstrip("/"))
                    if pair == want:
                        tr, q = ts.transform.translation, ts.transform.rotation
                        rows.append((stamp_of(ts.header), tr.x, tr.y, q.x, q.y, q.z, q.w))
            else:
                p, q = m.pose.pose.position, m.pose.pose.orientation
                rows.append((stamp_of(m.header), p.x, p.y, q.x, q.y, q.z, q.w))
        for t, x, y, *q in rows:
            norm = float(np.linalg.norm(q))
            if not (np.isfinite([t, x, y, norm]).all() and norm > 1e-6):
                self._warn(f"{where} t={t:.9f}: odometry pose x={x}, y={y}, quaternion {q} "
                           "cannot be used; left out")  # fmt: skip
                continue
            e = self._odom.tag(t, now)
            if e is None:
                self.counts["late"] += 1
                continue
            self._odom_t.setdefault(e, []).append(t)
            self._odom_p.setdefault(e, []).append(np.array([x, y, float(yaw_from_quat(q))]))
        return bool(rows)

    def _read_scans(self, now: float) -> bool:
        from mfcl_jax.io.bag import laserscan_points
        from mfcl_jax.io.pointcloud2 import pointcloud2_points
        from mfcl_jax.ros2.messages import stamp_of

        msgs = dds.take(self._scan_reader)
        xyz = self.params.planar.dim != 2
        for m in msgs:
            t = stamp_of(m.header)
            where = f"{self.params.scan_topic} t={t:.9f}"
            try:
                if self.params.cloud:
                    pts = pointcloud2_points(m, where, xyz=xyz)[0]
                else:
                    pts = laserscan_points(m, xyz)
            except DataError as e:
                self._warn(f"{e}; left out")
                continue
            e = self._scans.tag(t, now)
            if e is None:
                self.counts["late"] += 1
                continue
            self.frame_id = m.header.frame_id
            self._queue.setdefault(e, []).append((t, m.header.frame_id, pts))
        return bool(msgs)

    # ---------------------------------------------------------------- joining
    def _join(self) -> int:
        """Joins the current segment's waiting scans the odometry reaches; how many."""
        e = self._segment
        queue, ot = self._queue.get(e, []), self._odom_t.get(e, [])
        n = 0
        while queue and ot:
            t, frame, pts = queue[0]
            if t < ot[0] - TIME_TOL_S or (self._times and t <= self._times[-1]):
                queue.pop(0)
                self.counts["early" if t < ot[0] - TIME_TOL_S else "late"] += 1
                continue
            if t > ot[-1]:
                break  # wait for odometry at or after the scan: interpolate, as the batch does
            mount = self.mount(frame)
            if mount is None:
                break  # waiting for /tf_static
            queue.pop(0)
            i = int(np.searchsorted(ot, t))
            lo, hi = max(i - 1, 0), min(i + 1, len(ot))
            base = interpolate_se2(ot[lo:hi], np.asarray(self._odom_p[e][lo:hi]), [t])[0]
            self._times.append(t)
            self._poses.append(sensor_poses(base[None], mount)[0])
            self._planar_scans += self._planar.push(pts, f"{self.params.scan_topic} t={t:.9f}")
            n += 1
        # the odometry before the newest joined scan is no longer needed (bounded memory)
        if self._times and len(ot) > 2:
            keep = max(int(np.searchsorted(ot, self._times[-1])) - 1, 0)
            if keep > 0:
                del ot[:keep], self._odom_p[e][:keep]
        return n

    def _jumped(self) -> bool:
        """Both streams have moved past the current segment's epoch: a new segment."""
        return self._scans.epoch > self._segment and self._odom.epoch > self._segment

    def _check_silence(self, now: float) -> None:
        for name, stream in ((self.params.scan_topic, self._scans),
                             (self.params.odom_topic, self._odom)):  # fmt: skip
            heard = stream.heard if stream.heard is not None else self._start
            quiet = now - heard
            if quiet < self.params.silence_s:
                self._silent_since.pop(name, None)
                continue
            last = self._silent_since.get(name)
            if last is None or now - last >= self.params.silence_s:
                self._silent_since[name] = now
                what = "no message yet" if stream.heard is None else "no message"
                self.notify("silent", f"{name}: {what} for {quiet:.1f} s")

    def waiting(self) -> str | None:
        """Why no scan has joined yet, for a person (None once one has)."""
        if self._times:
            return None
        if self._scans.heard is None:
            return f"waiting for {self.params.scan_topic}"
        if self._odom.heard is None:
            return f"waiting for {self.params.odom_topic}"
        if self.frame_id and self.mount(self.frame_id) is None:
            return (f"waiting for {self.params.tf_static_topic}: "
                    f"{self.params.base_frame} -> {self.frame_id}")  # fmt: skip
        return "waiting for odometry at the scans' stamps"

    # ---------------------------------------------------------------- output
    @property
    def n_scans(self) -> int:
        return len(self._planar_scans)

    @property
    def segment(self) -> int:
        return self._segment

    @property
    def newest(self) -> float | None:
        """The newest scan stamp heard (s)."""
        return self._scans.newest

    def sequence(self) -> ScanSequence:
        n = len(self._planar_scans)
        return ScanSequence(np.asarray(self._times[:n]), list(self._planar_scans),
                            np.asarray(self._poses[:n]), self.params.scan_topic)  # fmt: skip

    def release(self, before: int) -> None:
        """Drops the points of the current segment's scans before index ``before``."""
        for i in range(self._released, min(before, len(self._planar_scans))):
            self._planar_scans[i] = _EMPTY
        self._released = max(self._released, before)

    def step(self) -> tuple[bool, bool]:
        """One read of every topic: ``(grew, jumped)``."""
        now = self._clock()
        if self._tf_reader is not None:
            self._read_tf_static()
        self._read_odometry(now)
        self._read_scans(now)
        before = self.n_scans
        self._join()
        self._check_silence(now)
        return self.n_scans > before, self._jumped()

    def prefixes(self) -> Iterator[ScanSequence]:
        """The current segment's scans, each time they grew; returns when both streams have
        jumped back in time (then ``next_segment``)."""
        while True:
            checkpoint()  # a stop whose exception was lost is raised here
            grew, jumped = self.step()
            if grew:
                yield self.sequence()
            elif jumped:
                return
            else:
                self._wait(self.poll)

    def next_segment(self) -> None:
        """Starts the next segment on the messages after the jump (what was left of the old
        one is dropped and counted as stale)."""
        old = self._segment
        self.counts["stale"] += len(self._queue.pop(old, []))
        self._odom_t.pop(old, None)
        self._odom_p.pop(old, None)
        self._segment = min(self._scans.epoch, self._odom.epoch)
        self._planar = PlanarStream(self.params.planar)
        self._reset_segment()
