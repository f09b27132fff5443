"""What ``mfcl ros2`` and ``mfcl play`` do with their flags: checks first (nothing starts
on a bad flag or plan), then the node until a signal, then the outputs, written atomically."""

from __future__ import annotations

import math
import sys

from mfcl_jax.io.errors import DataError

__all__ = ["run_node", "run_play", "node_params"]


def _err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def node_params(args):
    """``NodeParams`` from the flags (checked)."""
    from mfcl_jax.cli.inputs import planar_params
    from mfcl_jax.ros2.dds import dds_topic
    from mfcl_jax.ros2.node import NodeParams
    from mfcl_jax.ros2.topics import FeedParams
    from mfcl_jax.sources.planar import mount_3d

    if not (math.isfinite(args.silence) and args.silence > 0):
        raise DataError(f"ros2: --silence must be > 0 s, got {args.silence}")
    for flag in ("scan_topic", "cloud_topic", "odom_topic", "pose_topic", "status_topic"):
        value = getattr(args, flag)
        if value is not None:
            try:
                dds_topic(value)
            except DataError as e:
                raise DataError(f"ros2: --{flag.replace('_', '-')}: {e}") from None
    if args.lidar_offset is not None and args.lidar_mount is not None:
        raise DataError("ros2: give --lidar-offset or --lidar-mount, not both")
    mount3d, planar_mount = None, args.lidar_offset
    if args.lidar_mount is not None:
        planar_mount, mount3d = mount_3d(*args.lidar_mount)
    feed = FeedParams(
        scan_topic=args.cloud_topic or args.scan_topic, cloud=args.cloud_topic is not None,
        odom_topic=args.odom_topic, odom_frames=(args.odom_frame, args.base_frame),
        base_frame=args.base_frame, mount=planar_mount, planar=planar_params(args, mount3d),
        silence_s=float(args.silence), reliable=args.reliable,
    )  # fmt: skip
    return NodeParams(feed=feed, pose_topic=args.pose_topic, status_topic=args.status_topic,
                      map_frame=args.map_frame, publish_tf=args.publish_tf)  # fmt: skip


def run_node(args, progress) -> int:
    """``mfcl ros2``: runs until SIGINT / SIGTERM; exit 130 / 143 after writing the outputs."""
    from mfcl_jax.cli.common import check_viz, localize_params, start, verdict, viz_add
    from mfcl_jax.io import check_output, write_decisions
    from mfcl_jax.robot.signals import StopSignals, stop_name, stop_status

    params = node_params(args)
    inputs = list(args.floorplan)
    if args.out is not None:
        check_output(args.out, inputs=inputs)
    if args.viz is not None:
        check_viz(args.viz, [*inputs, args.out])
    if args.foxglove is not None and not 0 <= args.foxglove <= 65535:
        raise DataError(f"ros2: --foxglove PORT must be 0..65535, got {args.foxglove}")
    with StopSignals() as signals:
        node, viz, why, live, live_viz = None, None, None, None, None
        try:
            from mfcl_jax.ros2.dds import Bus
            from mfcl_jax.ros2.node import Node

            bus = Bus()
            node = Node(bus, params)
            _err(f"mfcl: ROS 2 domain {bus.domain}: reading {params.feed.scan_topic}, "
                 f"{params.feed.odom_topic}; publishing {params.pose_topic}, "
                 f"{params.status_topic}")  # fmt: skip
            start(progress)
            from mfcl_jax.floorplan.load import load_building
            from mfcl_jax.robot.localizer import Localizer
            from mfcl_jax.robot.viz import VizWriter

            with progress.stage(f"loading {' + '.join(map(str, args.floorplan))}"):
                fp = load_building(args.floorplan, storey=args.storey,
                                    free_thresh=args.free_thresh,
                                    occupied_thresh=args.occupied_thresh)  # fmt: skip
            lp = localize_params(args)
            viz = VizWriter(args.viz, fp) if args.viz is not None else None
            if args.foxglove is not None:
                from mfcl_jax.robot.viz_live import FoxgloveLive

                live = FoxgloveLive(args.foxglove, args.foxglove_host)
                live_viz = VizWriter(None, fp, live=live)
                _err(f"mfcl: Foxglove: ws://{live.host}:{live.port}")

            def on_window(result, rec):
                nonlocal viz, live_viz
                viz = viz_add(viz, result, rec)
                live_viz = viz_add(live_viz, result, rec)
                if not args.quiet:
                    _err(result.status(fp.offset))

            node.on_window = on_window
            node.run(Localizer(fp, lp))
        except KeyboardInterrupt as e:
            why = e
        except Exception as e:
            if node is not None and isinstance(e, DataError | OSError | ValueError):
                node.event("stop", f"error: {e}")
            raise
        with signals.writing():
            records = node.records if node is not None else []
            if node is not None:
                node.event("stop", f"stopped by {stop_name(why)}")
            _err(f"mfcl: stopped by {stop_name(why)}: {verdict(records)}")
            if node is not None:
                counts = {k: v for k, v in node.feed.counts.items() if v}
                if counts:
                    _err("mfcl: messages left out: " +
                         ", ".join(f"{v} {k}" for k, v in counts.items()))  # fmt: skip
            if args.out is not None:
                write_decisions(args.out, records)
                _err(f"decisions: {args.out}")
            if viz is not None:
                _err(f"viz: {viz.close()}")
            if live is not None:
                live.close()
    return stop_status(why)


def run_play(args) -> int:
    """``mfcl play DATASET``: publishes the dataset once, at ``--rate``."""
    import numpy as np

    from mfcl_jax.io.tf_static import sensor_poses
    from mfcl_jax.io.tum import read_tum
    from mfcl_jax.ros2.dds import Bus
    from mfcl_jax.ros2.play import Player, PlayParams
    from mfcl_jax.se2 import inverse_host
    from mfcl_jax.sources.dataset import load_dataset

    if not (math.isfinite(args.rate) and args.rate > 0):
        raise DataError(f"play: --rate must be > 0, got {args.rate}")
    if (args.dataset is None) == (args.bag is None):
        raise DataError("play: give a dataset folder or --bag, one of them")
    if args.bag is not None:
        return _play_bag(args)
    ds = load_dataset(args.dataset)
    o_times, o_poses = read_tum(args.dataset / "odometry.tum")  # at its own rate
    base = sensor_poses(o_poses, inverse_host(np.asarray(args.lidar_offset)))
    player = Player(Bus(), PlayParams(scan_topic=args.scan_topic, cloud=args.cloud,
                                      odom_topic=args.odom_topic, rate=args.rate,
                                      reliable=args.reliable))  # fmt: skip
    player.mount(args.lidar_offset)
    return _play(
        args,
        player,
        f"{len(ds.times)} scans of {args.dataset}",
        lambda: player.play(ds.times, ds.scans, o_times, base, offset=args.time_offset),
    )


def _play_bag(args) -> int:
    from mfcl_jax.io.bag import open_bag
    from mfcl_jax.ros2.dds import Bus
    from mfcl_jax.ros2.play import Player, PlayParams, bag_messages

    reader = open_bag(args.bag)
    types = {c.topic: c.msgtype for c in reader.connections}
    reader.close()
    for topic in (args.scan_topic, args.odom_topic):
        if topic not in types:
            raise DataError(f"{args.bag}: no topic {topic}; topics: {sorted(types)}")
    cloud = types[args.scan_topic].endswith("PointCloud2")
    msgs = bag_messages(args.bag, (args.scan_topic, args.odom_topic, "/tf_static"))
    player = Player(Bus(), PlayParams(scan_topic=args.scan_topic, cloud=cloud,
                                      odom_topic=args.odom_topic, rate=args.rate,
                                      reliable=args.reliable))  # fmt: skip
    return _play(
        args, player, f"{len(msgs)} messages of {args.bag}", lambda: player.play_messages(msgs)
    )


def _play(args, player, what: str, go) -> int:
    """Waits for readers, runs ``go()`` until it ends or a signal stops it (130 / 143)."""
    from mfcl_jax.robot.signals import StopSignals, stop_status
    from mfcl_jax.ros2.dds import domain_id

    if not player.wait_for_readers(args.wait):
        _err(f"mfcl: no reader of {args.scan_topic} and {args.odom_topic} after {args.wait:g} s; "
             "playing anyway")  # fmt: skip
    _err(f"mfcl: ROS 2 domain {domain_id()}: playing {what} at {args.rate:g}x")
    with StopSignals() as signals:
        stop = signals.run(go)
    if stop is not None:
        _err(f"mfcl: stopped after {player.sent} messages")
        return stop_status(stop)
    _err(f"mfcl: {player.sent} messages published")
    return 0
