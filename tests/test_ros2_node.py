"""``mfcl ros2`` as a process, over the real wire protocol: this test is another DDS
participant (Cyclone DDS on loopback) that plays a simulated walk onto ``/scan``, ``/odom``
(50 Hz, the robot's base) and ``/tf_static`` (the LiDAR's mounting), and reads back what
nav2 would read: ``/initialpose`` against ground truth, ``/mfcl/status`` window by window
against ``mfcl localize`` on the same recording, ``map -> odom`` on ``/tf``, and what a
Foxglove client receives over WebSocket; and the faults. The walk's first windows are
played first (they abstain: no pose), then the topics fall silent (a DEFER event), then the
whole walk is played from its start (time goes back: a new segment, which commits and
publishes the pose), then SIGTERM (exit 143, ``--out`` and ``--viz`` written)."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from mfcl_jax.io import read_decisions, read_tum  # noqa: E402
from mfcl_jax.io.tf_static import sensor_poses  # noqa: E402
from mfcl_jax.se2 import inverse_host  # noqa: E402

MFCL = str(Path(sys.executable).parent / "mfcl")
# test_cli's walk of the symmetric bays (R1 -> door line -> R4; the robot tests' one compiled
# step): 109 scans, 11 windows, DEFER until the walk nears the far wall, then COMMIT.
WAYPOINTS = [(1.0, 4.2), (3.0, 1.8), (27.0, 1.8)]
MOUNT = np.array([0.2, 0.1, math.pi / 2])  # the LiDAR on the base, sent on /tf_static
RATE = 16.0  # times real time


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    from mfcl_jax.floorplan import save_geojson
    from mfcl_jax.sim.scenes import symmetric_bays
    from mfcl_jax.sources.simulated import simulate_dataset

    root = tmp_path_factory.mktemp("ros2")
    fp = symmetric_bays().floorplan
    save_geojson(fp, root / "bays.geojson")
    ds = simulate_dataset(fp, WAYPOINTS, root / "ds", seed=3, odom_rate=50)
    return root, ds


class _Listener:
    """What a nav2 stack hears: every message of the node's topics, as it arrives."""

    def __init__(self):
        from mfcl_jax.ros2 import messages as M
        from mfcl_jax.ros2.dds import LATCHED, RELIABLE, SENSOR, Bus, take

        bus = Bus()
        readers = {"status": bus.reader("/mfcl/status", M.String, RELIABLE),
                   "pose": bus.reader("/initialpose", M.PoseWithCovarianceStamped, LATCHED),
                   "tf": bus.reader("/tf", M.TFMessage, SENSOR)}  # fmt: skip
        self.got = {k: [] for k in readers}
        self._stop = False

        def loop():
            while not self._stop:
                for k, r in readers.items():
                    self.got[k] += take(r)
                time.sleep(0.01)

        self._thread = threading.Thread(target=loop, daemon=True)
        self._thread.start()

    def status(self) -> list[dict]:
        return [json.loads(s.data) for s in self.got["status"]]

    def windows(self) -> list[dict]:
        return [s for s in self.status() if "event" not in s]

    def wait(self, what, timeout: float = 120.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if what():
                return True
            time.sleep(0.05)
        raise AssertionError(f"timed out; status so far: {self.status()[-5:]}")

    def close(self):
        self._stop = True
        self._thread.join()


def _drain(stream, lines):
    for line in stream:
        lines.append(line)


class _Foxglove:
    """A WebSocket client of the node's Foxglove server (``websockets``), subscribed to every
    channel it advertises; ``got[topic]`` the messages' JSON."""

    def __init__(self, url: str):
        self.got: dict[str, list] = {}
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._loop, args=(url,), daemon=True)
        self._thread.start()
        assert self._ready.wait(30)

    def _loop(self, url):
        import struct

        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        topics = {}
        protocols = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
        with connect(url, subprotocols=protocols) as ws:
            self._ws = ws
            self._ready.set()
            self._receive(ws, topics, struct, ConnectionClosed)

    def _receive(self, ws, topics, struct, ConnectionClosed):
        try:
            while True:
                m = ws.recv()
                if isinstance(m, str):
                    d = json.loads(m)
                    if d["op"] == "advertise":
                        subs = []
                        for c in d["channels"]:
                            topics[c["id"]] = c["topic"]
                            subs.append({"id": c["id"], "channelId": c["id"]})
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                elif m[0] == 1:  # message data: op, subscription id, log time, payload
                    sub, _ = struct.unpack("<IQ", m[1:13])
                    self.got.setdefault(topics[sub], []).append(json.loads(m[13:]))
        except ConnectionClosed:
            pass

    def close(self):
        self._ws.close()
        self._thread.join(timeout=10)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _base_truth(ds, t):
    """The robot base's true pose in the plan at ``t`` (ground truth is the sensor's)."""
    from mfcl_jax.io.timesync import interpolate_se2

    gt_t, gt = read_tum(ds / "groundtruth.tum")
    return sensor_poses(interpolate_se2(gt_t, gt, [t]), inverse_host(MOUNT))[0]


def test_node_over_dds_commits_publishes_and_survives_faults(walk, ros2_env, tmp_path):
    from mfcl_jax.ros2.dds import Bus
    from mfcl_jax.ros2.play import Player, PlayParams
    from mfcl_jax.sources.dataset import load_dataset

    root, ds = walk
    out, batch, viz = tmp_path / "node.jsonl", tmp_path / "batch.jsonl", tmp_path / "run.mcap"
    listener = _Listener()
    node = subprocess.Popen(
        [MFCL, "ros2", "--floorplan", str(root / "bays.geojson"), "--out", str(out),
         "--viz", str(viz),
         "--silence", "2", "--publish-tf", "--foxglove", "0", "--reliable"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    err: list[str] = []
    threading.Thread(target=_drain, args=(node.stderr, err), daemon=True).start()
    try:
        # the same recording decided by the batch path, while the node starts
        batch_run = subprocess.run([MFCL, "localize", str(ds), "--out", str(batch), "--quiet"],
                                   capture_output=True, text=True)  # fmt: skip
        assert batch_run.returncode == 0, batch_run.stderr
        listener.wait(lambda: any(s.get("event") == "start" and s["state"] == "DEFER"
                                  for s in listener.status()))  # fmt: skip
        listener.wait(lambda: any("Foxglove: ws://" in x for x in err))
        url = next(x for x in err if "Foxglove: ws://" in x).split("Foxglove: ")[1].strip()
        fox = _Foxglove(url)
        rec = load_dataset(ds)
        o_t, o_sensor = read_tum(ds / "odometry.tum")
        base = sensor_poses(o_sensor, inverse_host(MOUNT))
        want = read_decisions(batch)
        n = len(want)
        first = next(d for d in want if d["state"] == "COMMIT")
        assert 1 < first["k"] < n  # the walk abstains at first, then commits before its end
        short = want[: first["k"] - 1]
        player = Player(Bus(), PlayParams(rate=RATE, reliable=True))
        player.mount(MOUNT)
        assert player.wait_for_readers()

        # the walk's first windows only (they abstain): no pose, ever
        end = short[-1]["t"] + 1e-9
        cut = rec.times <= end
        player.play(rec.times[cut], [s for s, c in zip(rec.scans, cut, strict=True) if c],
                    o_t[o_t <= end], base[o_t <= end])  # fmt: skip
        listener.wait(lambda: len(listener.windows()) == len(short))
        got = listener.windows()
        assert [d["k"] for d in got] == list(range(1, len(short) + 1))
        assert [d["state"] for d in got] == [d["state"] for d in short]

        # silence: a DEFER event, never a guess
        def silent():
            return [s for s in listener.status() if s.get("event") == "silent"
                    and s["reason"].startswith("/scan: no message for")]  # fmt: skip

        listener.wait(silent, 30)
        assert silent()[0]["state"] == "DEFER" and silent()[0]["k"] == len(short)
        assert not listener.got["pose"]  # the abstaining segment published nothing

        # time goes back: the whole walk from its start, a new segment; window by window the
        # decisions of the same recording read from its folder
        player.play(rec.times, rec.scans, o_t, base)
        listener.wait(lambda: len(listener.windows()) == len(short) + n)
        assert [s["event"] for s in listener.status() if s.get("event") == "restart"] == ["restart"]
        got = listener.windows()[len(short) :]
        assert [d["k"] for d in got] == list(range(len(short) + 1, len(short) + n + 1))
        assert {d["segment"] for d in got} == {1}
        assert [d["state"] for d in got] == [d["state"] for d in want]
        assert [d["B1"] for d in got] == [d["B1"] for d in want]

        # /initialpose: once, at the segment's first COMMIT, the base's true pose within the
        # judging line, frame map, a covariance from the fit (positive, below the prior's 1 m)
        listener.wait(lambda: len(listener.got["pose"]) == 1)
        p = listener.got["pose"][0]
        t = _stamp(p)
        assert p.header.frame_id == "map" and abs(t - first["t"]) < 1e-6
        q = p.pose.pose.orientation
        yaw = 2 * math.atan2(q.z, q.w)
        truth = _base_truth(ds, t)
        pos = p.pose.pose.position
        assert math.hypot(pos.x - truth[0], pos.y - truth[1]) < 1.0
        assert abs(math.remainder(yaw - truth[2], 2 * math.pi)) < math.radians(5)
        cov = np.asarray(p.pose.covariance).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])]
        assert np.all(np.linalg.eigvalsh(cov) > 0) and np.all(np.diag(cov) < 1.0)
        # map -> odom: the committed anchor (the base's odometry placed by it)
        tf = [ts for m in listener.got["tf"] for ts in m.transforms]
        assert tf and tf[-1].header.frame_id == "map" and tf[-1].child_frame_id == "odom"
        a = want[-1]["anchor"]
        assert abs(tf[-1].transform.translation.x - a["x"]) < 0.05

        # Foxglove, live: a message on every channel; the decisions those of the status topic
        listener.wait(lambda: len(fox.got.get("/mfcl/decision", [])) == len(listener.windows()),
                      30)  # fmt: skip
        assert set(fox.got) == {
            "/mfcl/plan",
            "/mfcl/scan",
            "/mfcl/pose",
            "/mfcl/path",
            "/mfcl/alternatives",
            "/mfcl/state",
            "/mfcl/decision",
        }
        assert [d["k"] for d in fox.got["/mfcl/decision"]] == [d["k"] for d in listener.windows()]
        assert fox.got["/mfcl/plan"][0]["entities"][0]["lines"]
        assert any(m["poses"] for m in fox.got["/mfcl/pose"])  # the committed pose is drawn
        fox.close()

        node.send_signal(signal.SIGTERM)
        assert node.wait(timeout=60) == 143
        listener.wait(lambda: listener.status()[-1].get("event") == "stop", 10)
    finally:
        if node.poll() is None:
            node.kill()
        listener.close()
    text = "".join(err)
    total = len(listener.windows())
    assert f"mfcl: stopped by SIGTERM: {total} windows in 2 odometry segments" in text, text
    assert "Traceback" not in text
    written = read_decisions(out)
    assert [d["k"] for d in written] == list(range(1, total + 1))
    assert "mfcl: restart: time went back" in text
    from mcap.reader import make_reader

    with viz.open("rb") as f:  # the MCAP written at the stop: every window
        decided = [m for _, ch, m in make_reader(f).iter_messages() if ch.topic == "/mfcl/decision"]
    assert len(decided) == total
