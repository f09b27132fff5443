"""Benchmark: simulate every trajectory of both built-in scenes at d_s = 5, 6, 7 m.

For 1 and 10 seeds, the first call after ``jax.clear_caches()`` gives the compile + run time;
the median of ``--reps`` further calls gives the run time; compile = first - median. The ray
cast alone is timed the same way to show where the time goes (the rest is host work: odometry,
windows, voxel downsampling and packing). Prints a table and writes ``results/bench_simulate.csv``.

Run: ``python -m benchmarks.simulate [--reps 3] [--out results/bench_simulate.csv]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np
import pandas as pd

from mfcl_jax.sim import SimParams, cast, simulate
from mfcl_jax.sim.scenes import SCENES, get_scene
from mfcl_jax.sim.trajectory import sample_path
from mfcl_jax.windows.arrays import bucket

D_S = (5.0, 6.0, 7.0)


def _sim_all(scenes, seeds, params):
    out = [simulate(s, None, D_S, seeds, params) for s in scenes]
    for sim in out:
        jax.block_until_ready(sim.submaps.points)
    return out


def _cast_only(scenes, n_seeds, params):
    """The ray cast of the same scans, padded as ``simulate`` pads them (one call per scene)."""
    out = []
    for sc in scenes:
        poses = np.concatenate(
            [sample_path(wp, params.trajectory).poses for wp in sc.trajectories.values()] * n_seeds
        )
        s_cap, segs = bucket(len(poses)), sc.segments
        seg = np.zeros((bucket(len(segs), 64), 2, 2))
        seg[: len(segs)] = segs
        pad = np.concatenate([poses, np.repeat(poses[-1:], s_cap - len(poses), 0)])
        keys = jax.random.split(jax.random.PRNGKey(0), s_cap)
        out.append(
            cast(
                pad, seg, params.lidar, key=keys, seg_valid=np.arange(len(seg)) < len(segs)
            ).block_until_ready()
        )
    return out


def _timed(fn, reps):
    jax.clear_caches()
    t0 = time.perf_counter()
    result = fn()
    first = time.perf_counter() - t0
    runs = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t0)
    med = float(np.median(runs))
    return result, first, med


def main(argv=None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 10])
    ap.add_argument("--out", default="results/bench_simulate.csv")
    args = ap.parse_args(argv)
    params = SimParams()
    scenes = [get_scene(n) for n in SCENES]
    rows = []
    for n_seeds in args.seeds:
        seeds = list(range(n_seeds))
        sims, first, med = _timed(lambda seeds=seeds: _sim_all(scenes, seeds, params), args.reps)
        n_scans = sum(
            len(sample_path(wp, params.trajectory).poses) * n_seeds
            for s in scenes
            for wp in s.trajectories.values()
        )
        n_runs = sum(len(s.runs) for s in sims)
        n_sub = sum(s.submaps.n for s in sims)
        cap = "/".join(str(s.submaps.points.shape[1]) for s in sims)
        _, c_first, c_med = _timed(lambda n=n_seeds: _cast_only(scenes, n, params), args.reps)
        rows.append(
            dict(
                seeds=n_seeds,
                runs=n_runs,
                scans=n_scans,
                submaps=n_sub,
                capacity=cap,
                beams=params.lidar.n_beams,
                first_call_s=first,
                compile_s=max(first - med, 0.0),
                run_s=med,
                cast_compile_s=max(c_first - c_med, 0.0),
                cast_run_s=c_med,
                scans_per_s=n_scans / med,
                device=jax.devices()[0].platform,
            )
        )
    df = pd.DataFrame(rows)
    with pd.option_context("display.width", 160, "display.float_format", "{:.3f}".format):
        print(df.to_string(index=False))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(args.out, index=False)
    print(f"wrote {args.out}")
    return df


if __name__ == "__main__":
    main()
