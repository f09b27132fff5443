"""Benchmark: simulate every trajectory of both built-in scenes at d_s = 5, 6, 7 m.

The study's data path (``study.pipeline.prepare``): ``sources.simulated.simulate`` gives one
recording per (trajectory, seed) of a scene, ``windows.cut_many`` cuts each into windows at
every d_s (its LiDAR odometry refined once per recording) and ``windows.pack`` pads them into
one ``WindowBatch`` per scene. For 1 and 10 seeds, the first call after ``jax.clear_caches()``
gives the compile + run time; the median of ``--reps`` further calls gives the run time;
compile = first - median; ``sim_run_s`` and ``windows_run_s`` split that median into the
recordings (ray cast, drifting odometry) and the windows (LiDAR odometry, submaps, voxel
downsampling, packing). The ray cast alone is timed the same way to show where the time goes.
Prints a table and writes ``results/bench_simulate.csv``.

Run: ``python -m benchmarks.simulate [--reps 3] [--out results/bench_simulate.csv]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np
import pandas as pd

from mfcl_jax import windows as W
from mfcl_jax.sim import SimParams, cast
from mfcl_jax.sim.scenes import SCENES, get_scene
from mfcl_jax.sim.trajectory import sample_path
from mfcl_jax.sources.simulated import CHUNK, simulate

D_S = (5.0, 6.0, 7.0)


def _sim_all(scenes, seeds, params, stages=None):
    """One ``WindowBatch`` per scene (runs: trajectory x d_s x seed); ``stages`` collects
    the seconds of the recordings and of the windows."""
    out, t_sim, t_win = [], 0.0, 0.0
    for sc in scenes:
        t0 = time.perf_counter()
        recs = simulate(sc, None, seeds, params)
        t1 = time.perf_counter()
        todo = [(rec, ds) for rec in recs for ds in D_S]
        wins = W.cut_many((rec.seq, W.WindowParams(d_s=ds)) for rec, ds in todo)
        out.append(W.pack((rec.seq, w, 0) for (rec, _), w in zip(todo, wins, strict=True)))
        jax.block_until_ready(out[-1].submaps.points)
        t_sim, t_win = t_sim + t1 - t0, t_win + time.perf_counter() - t1
    if stages is not None:
        stages.append((t_sim, t_win))
    return out


def _cast_only(scenes, n_seeds, params):
    """The ray cast of the same scans, padded as ``simulate`` pads them (chunks of ``CHUNK``
    scans, surfaces in a power-of-two bucket)."""
    out = []
    for sc in scenes:
        poses = np.concatenate(
            [sample_path(wp, params.trajectory).poses for wp in sc.trajectories.values()] * n_seeds
        )
        segs = np.asarray(sc.segments)
        seg = np.zeros((1 << max(8, (len(segs) - 1).bit_length()), 2, 2))
        seg[: len(segs)] = segs
        s_cap = -(-len(poses) // CHUNK) * CHUNK
        pad = np.concatenate([poses, np.repeat(poses[-1:], s_cap - len(poses), 0)])
        keys = jax.random.split(jax.random.PRNGKey(0), s_cap)
        valid = np.arange(len(seg)) < len(segs)
        for a in range(0, s_cap, CHUNK):
            out.append(
                cast(
                    pad[a : a + CHUNK], seg, params.lidar, key=keys[a : a + CHUNK], seg_valid=valid
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
        stages = []
        sims, first, med = _timed(
            lambda seeds=seeds, st=stages: _sim_all(scenes, seeds, params, st), args.reps
        )
        later = np.asarray(stages[1:] or stages)  # the timed calls (not the first)
        n_scans = sum(
            len(sample_path(wp, params.trajectory).poses) * n_seeds
            for s in scenes
            for wp in s.trajectories.values()
        )
        n_runs = sum(b.runs.n_runs for b in sims)
        n_sub = sum(b.submaps.n for b in sims)
        cap = "/".join(str(b.submaps.points.shape[1]) for b in sims)
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
                sim_run_s=float(np.median(later[:, 0])),
                windows_run_s=float(np.median(later[:, 1])),
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
