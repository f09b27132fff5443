"""Streaming decision latency per window (``SelectiveInitializer.update``) against history length.

The candidates are the front-end's for ``three_rooms`` T1 (d_s = 6 m, 31 windows); the
stream replays them for ``--windows`` windows, each replay's odometry shifted by 100 m so
that the history keeps growing with new anchors. The initializer's buffers double when full,
so an update that grows a buffer compiles: those are reported apart (``compile``), every other
update is timed as a run (wall and process CPU), except the few that ran the rival search (the
layer about to commit), listed apart. Medians per history bin. Writes
``results/bench_stream.csv`` and ``results/bench_stream.png``.
Usage: ``python benchmarks/stream.py [--windows 128]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    from mfcl_jax.decision.stream import SelectiveInitializer

    from mfcl_jax import windows as W
    from mfcl_jax.frontend.driver import FrontEnd
    from mfcl_jax.sources.simulated import simulate

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=128)
    ap.add_argument("--out", default=str(ROOT / "results" / "bench_stream"))
    a = ap.parse_args(argv)

    rec = simulate("three_rooms", ["T1"], [0])[0]
    wp = W.WindowParams(d_s=6.0)
    w = W.cut(rec.seq, wp)
    fe = FrontEnd([rec.floorplan])
    wb = W.pack([(rec.seq, w, 0)], capacity=wp.capacity)
    cand = fe.register(wb.submaps, wb.building)
    K, kf = len(w), w.keyframes
    init = SelectiveInitializer(rec.floorplan)
    rows, prev_end = [], -1
    for n in range(a.windows):
        k, cycle = n % K, n // K
        if k == 0:
            prev_end = -1
        shift = np.array([0.0, 100.0 * cycle, 0.0])
        j0, j1 = w.bounds[k]
        traj = w.odometry[prev_end + 1 : j1 + 1] + shift
        prev_end = int(j1)
        m = cand.mask[k]
        caps = (init.H.shape[:2], init.traj.shape[0])
        n_search = init.searches
        c0, t0 = time.process_time(), time.perf_counter()
        d = init.update(
            cand.pose[k][m], cand.score[k][m], w.X[k] + shift, traj,
            window_start=int(j0) + cycle * len(kf), evidence=(w.points[k], w.origins[k]),
        )  # fmt: skip
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        grew = (init.H.shape[:2], init.traj.shape[0]) != caps or n == 0
        searched = init.searches != n_search
        rows.append(dict(window=n + 1, state=d.state, grew=grew, searched=searched,
                         wall_ms=1e3 * wall, cpu_ms=1e3 * cpu))  # fmt: skip
    df = pd.DataFrame(rows)
    bins = [0, 16, 32, 64, 128, 256, 512]
    df["history"] = pd.cut(df["window"], bins=bins).astype(str)
    plain = df[~df["grew"] & ~df["searched"]]
    run = plain.groupby("history", sort=False)[["wall_ms", "cpu_ms"]].median()
    run["updates"] = plain.groupby("history", sort=False).size()
    comp = df[df["grew"]][["window", "wall_ms"]].rename(columns={"wall_ms": "compile_ms"})
    search = df[df["searched"] & ~df["grew"]][["window", "wall_ms"]]
    out = pathlib.Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out.with_suffix(".csv"), index=False, float_format="%.4g")
    print("run (updates that did not grow a buffer), medians:")
    print(run.round(2).to_markdown())
    print("updates that grew a buffer (compile):")
    print(comp.round(0).to_markdown(index=False))
    print("updates that ran the rival search (about to commit; the first one compiles it):")
    print(search.round(0).to_markdown(index=False))
    print(f"load average {os.getloadavg()[0]:.2f}")
    fig, ax = plt.subplots(figsize=(6, 3.2))
    ok = plain
    ax.plot(ok["window"], ok["wall_ms"], ".", ms=3, label="update (wall)")
    ax.axhline(20, color="r", lw=0.8, ls="--", label="20 ms target")
    ax.set_xlabel("windows in the history")
    ax.set_ylabel("ms per window")
    ax.set_yscale("log")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"), dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
