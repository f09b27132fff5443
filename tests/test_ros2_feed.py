"""The ROS 2 wire format and the topic feed, over real DDS (Cyclone DDS on loopback): every
message type serialises to the bytes ROS 2's own CDR gives (``rosbags``' serializer), and a
recording played onto the topics by another participant comes out of ``TopicFeed`` as the
same scans and sensor poses, for LaserScan + Odometry with ``/tf_static`` and for
PointCloud2 + ``/tf``; a time jump ends the segment. No JAX, no node process."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from mfcl_jax.sources.data import data_dir

pytest.importorskip("cyclonedds")

from mfcl_jax.io.tf_static import sensor_poses  # noqa: E402
from mfcl_jax.ros2 import messages as M  # noqa: E402
from mfcl_jax.ros2.dds import Bus, dds_topic, domain_id  # noqa: E402
from mfcl_jax.ros2.feed import TopicFeed  # noqa: E402
from mfcl_jax.ros2.play import Player, PlayParams, laserscan, odometry_msg, pointcloud2  # noqa: E402
from mfcl_jax.ros2.topics import FeedParams  # noqa: E402
from mfcl_jax.se2 import inverse_host  # noqa: E402

MOUNT = (0.2, -0.1, np.pi / 2)


def _walk(n=40, seed=0):
    """Scans on the simulator's 720-beam ring and a 50 Hz base odometry of a 4 m walk."""
    rng = np.random.default_rng(seed)
    t = 100.0 + 0.5 * np.arange(n)
    ot = np.arange(t[0], t[-1] + 1e-9, 0.02)
    poses = np.stack([0.1 * (ot - t[0]), 0.02 * (ot - t[0]), 0.01 * (ot - t[0])], 1)
    ang = np.arange(720) * (2 * np.pi / 720)
    scans = []
    for _ in t:
        r = rng.uniform(1.0, 8.0, 720)
        keep = rng.random(720) > 0.1
        scans.append(np.stack([r * np.cos(ang), r * np.sin(ang)], 1)[keep])
    return t, scans, ot, poses


def test_every_message_is_ros2_cdr():
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    t, scans, ot, poses = _walk(2)
    msgs = {
        "sensor_msgs/msg/LaserScan": laserscan(t[0], scans[0], "laser"),
        "sensor_msgs/msg/PointCloud2": pointcloud2(t[0], scans[0][:50], "laser"),
        "nav_msgs/msg/Odometry": odometry_msg(ot[3], poses[3]),
        "geometry_msgs/msg/PoseWithCovarianceStamped": M.PoseWithCovarianceStamped(
            header=M.Header(stamp=M.time_msg(12.25), frame_id="map"),
            pose=M.PoseWithCovariance(pose=M.Pose(position=M.Point(x=1.5, y=-2.0)),
                                      covariance=[float(i) for i in range(36)]),
        ),  # fmt: skip
        "tf2_msgs/msg/TFMessage": M.TFMessage([M.TransformStamped(
            header=M.Header(stamp=M.time_msg(3.0), frame_id="base_link"),
            child_frame_id="laser",
            transform=M.Transform(M.Vector3(0.2, 0.0, 0.3), M.yaw_quaternion(0.5)))]),
        "std_msgs/msg/String": M.String(data='{"state": "DEFER"}'),
    }  # fmt: skip
    for name, msg in msgs.items():
        ours = msg.serialize()
        theirs = bytes(ts.serialize_cdr(ts.deserialize_cdr(ours, name), name))
        assert ours == theirs, name
        back = ts.deserialize_cdr(ours, name)
        assert back.__msgtype__ == name


def test_names_and_domain():
    assert dds_topic("/scan") == "rt/scan" and dds_topic("robot1/odom") == "rt/robot1/odom"
    for bad in ("", "/", "/1scan", "/a b"):
        with pytest.raises(Exception, match="topic name"):
            dds_topic(bad)
    assert domain_id({}) == 0 and domain_id({"ROS_DOMAIN_ID": "42"}) == 42
    with pytest.raises(Exception, match="ROS_DOMAIN_ID.*'x'"):
        domain_id({"ROS_DOMAIN_ID": "x"})


def _play_and_feed(params: FeedParams, play: PlayParams, t, scans, ot, poses, jump=False):
    """Plays the walk (twice, the second from the start again, with ``jump``) from a second
    participant; returns the feed's last prefix of each segment and its events."""
    events = []
    feed = TopicFeed(Bus(), params, lambda e, r: events.append((e, r)))
    player = Player(Bus(), play)
    player.mount(MOUNT)
    assert player.wait_for_readers()

    def go():
        player.play(t, scans, ot, poses)
        if jump:
            player.play(t, scans, ot, poses)

    th = threading.Thread(target=go, daemon=True)
    th.start()
    out = []
    for i in range(2 if jump else 1):
        for seq in feed.prefixes():
            if len(seq) == len(t):
                break
        out.append(seq)
        if jump and i == 0:
            for _ in range(500):  # the second play starts: both streams go back in time
                if feed.step()[1]:
                    break
                time.sleep(0.01)
            feed.next_segment()
    th.join()
    return out, events, feed


def test_laserscan_odometry_and_tf_static_give_the_recording(ros2_env):
    t, scans, ot, poses = _walk()
    feed_p = FeedParams(silence_s=30.0, reliable=True)  # nothing lost: every scan compared
    play = PlayParams(rate=20.0, reliable=True)
    (seq,), events, feed = _play_and_feed(feed_p, play, t, scans, ot, poses)
    assert len(seq) == len(t) and np.allclose(seq.times, t)
    want = sensor_poses(np.asarray([np.interp(t, ot, poses[:, i]) for i in range(3)]).T, MOUNT)
    assert np.allclose(seq.odometry, want, atol=1e-6)
    for got, sent in zip(seq.scans, scans, strict=True):
        assert got.shape == sent.shape and np.allclose(got, sent, atol=1e-5)
    assert feed.frame_id == "laser" and not any(e == "warning" for e, _ in events)


def test_cloud_and_tf_odometry_and_a_time_jump(ros2_env):
    t, scans, ot, poses = _walk(20)
    feed_p = FeedParams(cloud=True, odom_topic="/tf", silence_s=30.0, mount=MOUNT, reliable=True)
    play = PlayParams(cloud=True, odom_topic="/tf", rate=20.0, reliable=True)
    (a, b), _, feed = _play_and_feed(feed_p, play, t, scans, ot, poses, jump=True)
    base = np.asarray([np.interp(t, ot, poses[:, i]) for i in range(3)]).T
    for seq in (a, b):  # each segment: the whole walk, nothing of the other
        assert np.allclose(seq.times, t)
        assert np.allclose(seq.odometry, sensor_poses(base, MOUNT), atol=1e-6)
        assert np.allclose(seq.scans[-1], scans[-1], atol=1e-5)
    assert feed.segment == 1


def test_silence_and_bad_messages_are_reported(ros2_env):
    events = []
    clock = [0.0]
    feed = TopicFeed(Bus(), FeedParams(silence_s=2.0, mount=(0.0, 0.0, 0.0)),
                     lambda e, r: events.append((e, r)), clock=lambda: clock[0])  # fmt: skip
    w = Bus().writer("/odom", M.Odometry)
    clock[0] = 2.5
    feed.step()
    assert ("silent", "/scan: no message yet for 2.5 s") in events
    assert ("silent", "/odom: no message yet for 2.5 s") in events
    bad = odometry_msg(5.0, (1.0, 2.0, 0.0))
    bad.pose.pose.orientation = M.Quaternion(0.0, 0.0, 0.0, 0.0)
    for _ in range(200):
        if w.get_matched_subscriptions():
            w.write(bad)
        feed.step()
        if any(e == "warning" for e, _ in events):
            break
        time.sleep(0.02)
    warn = [r for e, r in events if e == "warning"]
    assert warn and "/odom t=5.000000000" in warn[0] and "quaternion" in warn[0]
    assert feed.counts["bad"] >= 1 and feed.n_scans == 0


def test_inverse_mount_round_trip():
    base = np.array([[1.0, 2.0, 0.3]])
    sensor = sensor_poses(base, MOUNT)
    assert np.allclose(sensor_poses(sensor, inverse_host(np.asarray(MOUNT))), base)


BAG = data_dir() / "laser" / "intel.orig.bag"


@pytest.mark.skipif(not BAG.is_file(), reason=f"real data {BAG} is absent")
def test_the_intel_bag_over_dds_is_what_the_batch_reads(ros2_env):
    """The raw Intel bag's own messages (converted from ``rosbags``: real LaserScans with
    out-of-range returns, real /odom, its /tf_static) played at 40x for its first 60 s: the
    feed's scans and sensor poses are ``read_bag``'s (the batch path) at the same stamps.
    Best effort, as a LiDAR driver publishes: a loaded machine may lose a scan or two."""
    from mfcl_jax.io import read_bag
    from mfcl_jax.ros2.play import bag_messages

    msgs = bag_messages(BAG, seconds=60.0)
    feed = TopicFeed(Bus(), FeedParams(silence_s=30.0), lambda e, r: None)
    player = Player(Bus(), PlayParams(rate=40.0))
    assert player.wait_for_readers()
    th = threading.Thread(target=player.play_messages, args=(msgs,), daemon=True)
    th.start()
    n_scans = sum(topic == "/scan" for _, topic, _ in msgs)
    seq, end = None, time.monotonic() + 30
    while time.monotonic() < end and (seq is None or len(seq) < n_scans - 2):
        grew, _ = feed.step()
        seq = feed.sequence() if feed.n_scans else None
        time.sleep(0.01)
    th.join()
    bag = read_bag(BAG, "/scan", "/odom", base_frame="base_link")
    j = np.searchsorted(bag.times, seq.times)
    assert len(seq) >= n_scans - 2 and np.allclose(bag.times[j], seq.times, atol=1e-9)
    assert np.allclose(bag.odometry[j], seq.odometry, atol=1e-9)
    for i in (0, len(seq) // 2, len(seq) - 1):
        assert np.allclose(bag.scans[j[i]], seq.scans[i], atol=1e-6)
