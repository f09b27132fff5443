"""Streaming decision latency per window (``decision.layer.update``) against history length.

The candidates are the front-end's for ``three_rooms`` T1 (d_s = 6 m, 31 windows); the
stream replays them for ``--windows`` windows, each replay's odometry shifted by 100 m so
that the history keeps growing with new anchors. The layer runs with the robot's capacities
(``robot.localizer.ROBOT_CAPS``: 64 windows, 1024 keyframes), so a long run's older windows
leave the history and every update does the same work. The first update compiles (reported
apart, ``compile``); the updates that ran the rival search (the layer about to commit), the
certification, the uniqueness test (``--policy ours_unique*``) or the evidence grid
(``--policy ours_grid``: it runs at every window until the lane commits; ``mfcl localize
--early-commit``) are listed apart; every other update is timed as a run (wall and process
CPU). Medians per history bin. Writes ``results/bench_stream.csv``, ``.md`` and ``.png``
(``bench_stream_<policy>.*`` for another policy).
Usage: ``python benchmarks/stream.py [--windows 512] [--policy ours_unique]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
BINS = [0, 16, 32, 64, 128, 256, 512, 1024]


def main(argv=None) -> int:
    import jax
    import jax.numpy as jnp

    from mfcl_jax import windows as W
    from mfcl_jax.decision import layer, rivals
    from mfcl_jax.decision.lanes import ROBOT_POLICIES, make_lanes
    from mfcl_jax.decision.maps import decision_maps
    from mfcl_jax.frontend.driver import FrontEnd
    from mfcl_jax.robot.localizer import ROBOT_CAPS
    from mfcl_jax.sources.simulated import simulate

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=512)
    ap.add_argument("--out", help="output stem (default results/bench_stream[_<policy>])")
    ap.add_argument("--policy", default="ours", choices=ROBOT_POLICIES)
    a = ap.parse_args(argv)
    suffix = "" if a.policy == "ours" else f"_{a.policy}"
    a.out = a.out or str(ROOT / "results" / f"bench_stream{suffix}")

    rec = simulate("three_rooms", ["T1"], [0])[0]
    fp = rec.floorplan
    w = W.cut(rec.seq, W.WindowParams(d_s=6.0))
    wb = W.pack([(rec.seq, w, 0)], capacity=4096)
    cand = FrontEnd([fp]).register(wb.submaps, wb.building)
    K, caps = len(w), ROBOT_CAPS
    p, lanes, spec = make_lanes(None, (a.policy,), primary=a.policy)
    maps = jax.tree.map(jnp.asarray, decision_maps(fp, min_iou=spec.min_iou))
    fields = jax.tree.map(jnp.asarray, rivals.rival_fields(fp))
    state = layer.init(maps, p.as_arrays(), caps, jax.tree.map(jnp.asarray, lanes), spec, fields,
                       rivals.image_size([fp]))  # fmt: skip
    world, memory = layer.split(state)

    def step(world, memory, ev):
        s, d = layer.update(layer.join(world, memory), ev)
        return layer.split(s)[1], jax.tree.map(lambda x: x[0], d)

    step = jax.jit(step, donate_argnums=(1,))
    ev_p, ev_o, ev_m, end_p, end_m = (np.asarray(x) for x in (
        wb.evidence.points, wb.evidence.origins, wb.evidence.mask, wb.evidence.end_points,
        wb.evidence.end_mask))  # fmt: skip
    rows, prev_end = [], -1
    n_kf = len(w.keyframes)
    for n in range(a.windows):
        k, cycle = n % K, n // K
        if k == 0:
            prev_end = -1
        shift = np.array([0.0, 100.0 * cycle, 0.0])
        j0, j1 = (int(v) for v in w.bounds[k])
        traj = np.asarray(w.odometry[prev_end + 1 : j1 + 1] + shift, np.float32)
        prev_end = j1
        tr = np.zeros((caps.step, 3), np.float32)
        tr[: len(traj)] = traj[-caps.step :]
        ev = layer.WindowEvidence(
            Y=cand.pose[k], score=cand.score[k], mask=cand.mask[k],
            X=np.asarray(w.X[k] + shift, np.float32), traj=tr,
            traj_mask=np.arange(caps.step) < min(len(traj), caps.step),
            head=np.zeros((0, 3), np.float32), head_mask=np.zeros(0, bool),
            start=np.int32(j0 + cycle * n_kf), ev_points=ev_p[k], ev_origins=ev_o[k],
            ev_mask=ev_m[k], valid=np.bool_(True), last=np.bool_(False),
            restart=np.bool_(False), end_points=end_p[k], end_mask=end_m[k],
        )  # fmt: skip
        c0, t0 = time.process_time(), time.perf_counter()
        memory, d = step(world, memory, ev)
        d = jax.tree.map(np.asarray, d)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rows.append(dict(window=n + 1, state=int(d.state), searched=bool(d.searched),
                         certified=bool(d.certified), tested=not np.isnan(float(d.llr)),
                         dropped=int(d.dropped), wall_ms=1e3 * wall,
                         cpu_ms=1e3 * cpu))  # fmt: skip
    df = pd.DataFrame(rows)
    df["history"] = pd.cut(df["window"], bins=BINS).astype(str)
    plain = df[(df["window"] > 1) & ~df["searched"] & ~df["certified"] & ~df["tested"]]
    run = plain.groupby("history", sort=False)[["wall_ms", "cpu_ms"]].median()
    run["updates"] = plain.groupby("history", sort=False).size()
    out = pathlib.Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    print(f"compile (first update): {df['wall_ms'].iloc[0] / 1e3:.1f} s")
    extra = df[(df["window"] > 1) & (df["searched"] | df["certified"]) & ~df["tested"]]
    print(f"certified or searched updates: {len(extra)}, median "
          f"{extra['wall_ms'].median():.1f} ms")  # fmt: skip
    tested = df[(df["window"] > 1) & df["tested"]]
    test_name = "evidence grid" if "grid" in a.policy else "uniqueness test"
    if len(tested):
        print(f"updates with the {test_name}: {len(tested)}, median "
              f"{tested['wall_ms'].median():.1f} ms")  # fmt: skip
    print(run.round(2).to_string())
    load = os.getloadavg()[0]
    print(f"load1 {load:.2f}")
    table = run.round(2).reset_index()
    table.loc[len(table)] = ["compile (first update)", df["wall_ms"].iloc[0], None, 1]
    table.loc[len(table)] = ["certified or searched", extra["wall_ms"].median(), None, len(extra)]
    if len(tested):
        table.loc[len(table)] = [test_name, tested["wall_ms"].median(), None, len(tested)]
    note = f"\n\nMedians in ms; load average {load:.2f} on {os.cpu_count()} cores at the end.\n"
    out.with_suffix(".md").write_text(table.to_markdown(index=False, floatfmt=".1f") + note)
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(plain["window"], plain["wall_ms"], ".", ms=3, label="update (wall)")
    ax.plot(extra["window"], extra["wall_ms"], "x", ms=4, label="with certification/search")
    if len(tested):
        ax.plot(tested["window"], tested["wall_ms"], "+", ms=5, label=f"with the {test_name}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("windows of history")
    ax.set_ylabel("ms per window")
    ax.axvline(caps.windows, color="grey", lw=0.8, ls=":")
    ax.text(caps.windows, ax.get_ylim()[1], " history capacity", va="top", fontsize=8)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"), dpi=110)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
