"""What the live ROS 2 node (``mfcl ros2``) costs a robot: start, latency, memory, dropped windows.

Two replays onto real DDS topics (Cyclone DDS on loopback, a domain of their own), at real
rate, with the node in a subprocess and this script as the robot (publisher) and as nav2
(a reader of ``/initialpose`` and ``/mfcl/status``):

- ``office``: the README's Office_A walk, simulated with 100 Hz odometry, against the IFC
  model (about 80 s of walk);
- ``intel``: the raw Intel lab bag, its own messages (LaserScan at 5 Hz, ``/odom`` at 10 Hz,
  ``/tf_static``) for ``--minutes`` minutes (30 by default), against the occupancy map of the
  whole log (``sources.logs.full_map``).

Latency is measured from the publication of the window's last scan; it includes the wait
for the first odometry message at or after that scan's stamp (the scan's pose is
interpolated there): up to 10 ms with the office walk's 100 Hz odometry, up to 100 ms with
the Intel bag's 10 Hz.

Before each replay ``mfcl localize`` decides the same messages from the recording (a dataset
folder, or ``--bag``): it fills the compilation cache (the node then starts warm, as on a
robot that ran before) and gives the windows the node must decide (none dropped, the same
states). Per replay: the node's first status message after its process started; per window
the latency from the publication of the window's last scan to the arrival of its status
message; the node's resident memory every 5 s (``/proc``); ``/initialpose`` against ground
truth (the simulator's, or the corrected log's poses matched to the bag's scans).

Writes ``results/bench_ros2_windows.csv``, ``results/bench_ros2_memory.csv``,
``results/bench_ros2.md`` and ``results/bench_ros2.png``, and pastes the table into
``docs/speed.md`` (block ``bench_ros2``; ``--paste`` alone re-pastes the written one). Usage:
``python benchmarks/ros2_node.py [--minutes 30] [--only office|intel]`` (the minutes of the
bag, plus about 5 minutes).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
import pandas as pd

from mfcl_jax.sources.data import data_dir

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from benchmarks._ros2_sides import Memory, Nav2Side  # noqa: E402
from benchmarks._versions_cases import OFFICE_IFC, WAYPOINTS  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
BAG = data_dir() / "laser" / "intel.orig.bag"
MFCL = [sys.executable, "-c", "import sys; from mfcl_jax.cli import main; sys.exit(main())"]
LOOPBACK = (
    '<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto"
    '</ParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain>'
    "</CycloneDDS>"
)


def log(text: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {text}", flush=True)


def replay(name, plan, messages, args_extra, env, seconds=None):
    """Starts the node, plays ``messages`` ``[(t, topic, sample)]`` (``/scan``, ``/odom``,
    ``/tf_static``) at real rate (``seconds`` of them at most), stops it; returns (windows,
    memory, poses, first status s, the last scan stamp played)."""
    from mfcl_jax.ros2 import messages as M
    from mfcl_jax.ros2.dds import LATCHED, RELIABLE, SENSOR, Bus, take  # noqa: F401

    bus = Bus()
    writers = {"/scan": bus.writer("/scan", M.LaserScan, SENSOR),
               "/odom": bus.writer("/odom", M.Odometry, RELIABLE),
               "/tf_static": bus.writer("/tf_static", M.TFMessage, LATCHED)}  # fmt: skip
    nav2 = Nav2Side()
    t_start = time.monotonic()
    node = subprocess.Popen([*MFCL, "ros2", "--floorplan", str(plan), "--quiet", *args_extra],
                            env=env, stderr=subprocess.PIPE, text=True)  # fmt: skip
    mem = Memory(node.pid)
    while not nav2.status and node.poll() is None:
        time.sleep(0.01)
    first_status = nav2.status[0][0] - t_start if nav2.status else math.nan
    while not all(w.get_matched_subscriptions() for w in writers.values()):
        time.sleep(0.02)
    t0 = next(t for t, topic, _ in messages if topic != "/tf_static")
    if seconds is not None:
        messages = [m for m in messages if m[1] == "/tf_static" or m[0] - t0 <= seconds]
    sent, last = {}, None
    w0 = time.monotonic()
    span = messages[-1][0] - t0
    log(f"{name}: playing {len(messages)} messages ({span:.0f} s) at real rate")
    for t, topic, m in messages:
        if topic != "/tf_static":
            wait = w0 + (t - t0) - time.monotonic()
            if wait > 0:
                time.sleep(wait)
        writers[topic].write(m)
        if topic == "/scan":
            last = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
            sent[round(last, 6)] = time.monotonic()
    time.sleep(5.0)  # the last windows, then stop
    node.terminate()
    err = node.communicate(timeout=120)[1]
    mem.close()
    nav2.close()
    rows = []
    for arrived, s in nav2.windows():
        published = sent.get(round(s["t"], 6), math.nan)
        rows.append({"case": name, "k": s["k"], "t": s["t"], "state": s["state"],
                     "latency_ms": 1e3 * (arrived - published)})  # fmt: skip
    log(f"{name}: node stderr tail: {err.strip().splitlines()[-2:]}")
    return rows, mem.rows, nav2.poses, first_status, last


def _office(tmp: pathlib.Path, env: dict):
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.io import read_tum
    from mfcl_jax.ros2.messages import TFMessage
    from mfcl_jax.ros2.play import _transform, laserscan, odometry_msg
    from mfcl_jax.sources.dataset import load_dataset
    from mfcl_jax.sources.simulated import simulate_dataset

    ds = tmp / "office"
    wp = np.loadtxt(WAYPOINTS.splitlines()[1:], delimiter=",")
    simulate_dataset(load_floorplan(OFFICE_IFC, storey="Level 1"), wp, ds, seed=0, odom_rate=100)
    expected = tmp / "office.jsonl"
    subprocess.run([*MFCL, "localize", str(ds), "--out", str(expected), "--quiet"], env=env,
                   check=True)  # fmt: skip
    rec = load_dataset(ds)
    ot, op = read_tum(ds / "odometry.tum")
    msgs = [(0.0, "/tf_static", TFMessage([_transform(0.0, "base_link", "laser", (0, 0, 0))]))]
    msgs += sorted([(t, "/odom", odometry_msg(t, p)) for t, p in zip(ot, op, strict=True)]
                   + [(t, "/scan", laserscan(t, s, "laser"))
                      for t, s in zip(rec.times, rec.scans, strict=True)],
                   key=lambda e: (e[0], e[1] == "/scan"))  # fmt: skip
    gt_t, gt = read_tum(ds / "groundtruth.tum")
    # the node reads the plan the batch read (the walk's storey, as the dataset holds it)
    return ds / "floorplan.geojson", msgs, expected, (gt_t, gt)


def _intel(tmp: pathlib.Path, env: dict, minutes: float):
    from mfcl_jax.io import read_bag
    from mfcl_jax.ros2.play import bag_messages
    from mfcl_jax.sources.bagtruth import bag_ground_truth, truth_at_scans
    from mfcl_jax.sources.logs import full_map, read_log

    plan = full_map("intel").yaml_path
    expected = tmp / "intel.jsonl"
    subprocess.run([*MFCL, "localize", "--bag", str(BAG), "--floorplan", str(plan),
                    "--tf-static", "--out", str(expected), "--quiet"], env=env,
                   check=True)  # fmt: skip
    msgs = bag_messages(BAG, seconds=minutes * 60.0)
    bag = read_bag(BAG, "/scan", "/odom")
    logd = read_log("intel")
    off, bi, li, agree = bag_ground_truth(bag, logd)
    good = agree > 0.95
    bi, order = np.unique(bi[good], return_index=True)
    # every bag scan's true pose: the matched corrected poses, carried between them by the
    # bag's odometry (as the benchmark's bag windows are scored; sources.bagtruth)
    poses, _ = truth_at_scans(bag, np.arange(len(bag)), bi, logd.poses[li[good]][order])
    truth = (bag.times, poses)
    return plan, msgs, expected, truth


def _pose_error(poses, truth):
    """Per /initialpose: (t, position error m, heading error deg) against the nearest truth."""
    out = []
    gt_t, gt = truth
    for _, p in poses:
        t = p.header.stamp.sec + 1e-9 * p.header.stamp.nanosec
        j = int(np.argmin(np.abs(np.asarray(gt_t) - t)))
        if abs(gt_t[j] - t) > 0.05:
            out.append((t, math.nan, math.nan))
            continue
        q = p.pose.pose.orientation
        yaw = 2 * math.atan2(q.z, q.w)
        pos = p.pose.pose.position
        out.append((t, math.hypot(pos.x - gt[j][0], pos.y - gt[j][1]),
                    abs(math.degrees(math.remainder(yaw - gt[j][2], 2 * math.pi)))))  # fmt: skip
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=30.0, help="minutes of the Intel bag (30)")
    ap.add_argument("--only", choices=("office", "intel"))
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results")
    ap.add_argument("--paste", action="store_true", help="only paste the written table")
    args = ap.parse_args(argv)
    if args.paste:
        return _paste(args.out / "bench_ros2.md")
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="bench_ros2_"))
    env = dict(os.environ, CYCLONEDDS_URI=LOOPBACK, ROS_DOMAIN_ID=str(150 + os.getpid() % 50),
               MFCL_CACHE_DIR=str(tmp / "cache"), JAX_PLATFORMS="cpu")  # fmt: skip
    os.environ.update({k: env[k] for k in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")})
    windows, memory, summary = [], [], []
    cases = [c for c in ("office", "intel") if args.only in (None, c)]
    for name in cases:
        log(f"{name}: preparing (the batch run fills the compilation cache)")
        if name == "office":
            plan, msgs, expected, truth = _office(tmp, env)
        else:
            plan, msgs, expected, truth = _intel(tmp, env, args.minutes)
        rows, mem, poses, first, t_end = replay(name, plan, msgs, [], env)
        scan_t = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                  for _, topic, m in msgs if topic == "/scan"]  # fmt: skip
        want = [json.loads(x) for x in expected.read_text().splitlines()]
        want = [w for w in want if w["t"] <= t_end]
        got = {r["k"]: r for r in rows}
        same = sum(got.get(w["k"], {}).get("state") == w["state"] for w in want)
        errs = _pose_error(poses, truth)
        lat = np.asarray([r["latency_ms"] for r in rows], float)
        mib = np.asarray([m for _, m in mem])
        late = [m for s, m in mem if s >= 120.0] or list(mib)
        summary.append({
            "case": name, "played_s": round(t_end - scan_t[0], 1),
            "first_status_s": round(first, 2), "windows": len(rows),
            "windows_batch": len(want), "same_state": same,
            "latency_median_ms": round(float(np.nanmedian(lat)), 1),
            "latency_p95_ms": round(float(np.nanpercentile(lat, 95)), 1),
            "rss_after_2min_MiB": round(late[0], 1), "rss_last_MiB": round(float(mib[-1]), 1),
            "rss_max_MiB": round(float(mib.max()), 1),
            "initialposes": len(poses),
            "pose_err_m": ";".join(f"{e:.3f}" for _, e, _ in errs),
            "pose_err_deg": ";".join(f"{d:.2f}" for _, _, d in errs),
        })  # fmt: skip
        log(f"{name}: {summary[-1]}")
        windows += rows
        memory += [{"case": name, "s": s, "rss_MiB": m} for s, m in mem]
    args.out.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(windows).to_csv(args.out / "bench_ros2_windows.csv", index=False)
    pd.DataFrame(memory).to_csv(args.out / "bench_ros2_memory.csv", index=False)
    table = pd.DataFrame(summary).to_markdown(index=False)
    (args.out / "bench_ros2.md").write_text(
        "# `mfcl ros2` replayed at real rate (benchmarks/ros2_node.py)\n\n" + table + "\n"
    )
    _figure(windows, memory, args.out / "bench_ros2.png")
    print(table)
    return _paste(args.out / "bench_ros2.md")


def _paste(md: pathlib.Path) -> int:
    """The table of ``md`` (its title line left out) into ``docs/speed.md``'s block."""
    from mfcl_jax.study.readme import update_block

    lines = [x for x in md.read_text().splitlines() if not x.startswith("# ")]
    with tempfile.TemporaryDirectory() as tmp:
        table = pathlib.Path(tmp) / "table.md"
        table.write_text("\n".join(lines).strip("\n") + "\n")
        if not update_block(ROOT / "docs" / "speed.md", "bench_ros2", table):
            log("docs/speed.md has no bench_ros2 block: not pasted")
    return 0


def _figure(windows, memory, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    w, m = pd.DataFrame(windows), pd.DataFrame(memory)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for case, g in w.groupby("case"):
        ax[0].plot(g["k"], g["latency_ms"], ".", label=case)
    ax[0].set(xlabel="window k", ylabel="last scan -> status (ms)", yscale="log",
              title="latency per window")  # fmt: skip
    ax[0].legend()
    for case, g in m.groupby("case"):
        ax[1].plot(g["s"] / 60, g["rss_MiB"], label=case)
    ax[1].set(xlabel="minutes since the node started", ylabel="resident memory (MiB)",
              title="node memory")  # fmt: skip
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    sys.exit(main())
