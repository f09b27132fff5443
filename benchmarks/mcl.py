"""Benchmark: the Monte Carlo localization peer on the simulator's runs of both built-in scenes.

Every trajectory of ``three_rooms`` and ``symmetric_bays`` x 3 simulator seeds (12 runs) x 3
filter seeds, read at the d_s = 6 m window ends, for each particle count, with the LiDAR's full
range and with the scans cropped at 10 m (the evidence our windows keep). After
``jax.clear_caches()``, an ahead-of-time ``lower().compile()`` gives the compile time, the
first call compile + run, and the median of ``--reps`` further calls the run time. The cost is
quoted per filter step (one keyframe of one (run, seed)); padded steps are not counted, though
the batch computes them. Accuracy columns come from the same traces: the share of (run, seed)
pairs whose final mean pose is correct (< 1 m, < 5 deg), and coverage / risk of the default
commit rule (spread <= 0.5 m and 10 deg) over all windows. Prints a table and writes
``results/bench_mcl.csv``.

Run: ``python -m benchmarks.mcl [--particles 4096 8192 16384] [--reps 3] [--crop none 10]``
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import jax
import numpy as np
import pandas as pd

from mfcl_jax import se2
from mfcl_jax.peers import MCLParams, commits, make_mcl, prepare_mcl_inputs
from mfcl_jax.score import CORRECT_XY, CORRECT_YAW_DEG
from mfcl_jax.sources.simulated import simulate as scene_recordings
from mfcl_jax.windows import travelled, window_bounds

SCENES = ("three_rooms", "symmetric_bays")
SIM_SEEDS = (0, 1, 2)
FILTER_SEEDS = (0, 1, 2)
D_S, STEP = 6.0, 2.0


def _runs():
    recs = [r for s in SCENES for r in scene_recordings(s, None, SIM_SEEDS)]
    ends = [window_bounds(travelled(r.seq.odometry), D_S, STEP)[:, 1] for r in recs]
    return recs, ends


def _accuracy(trace, recs, ends):
    """Final-pose correctness and commit coverage / risk over all windows."""
    K = trace.pose.shape[2]
    truth = np.zeros((len(recs), K, 3))
    for r, (rec, we) in enumerate(zip(recs, ends, strict=True)):
        truth[r, : len(we)] = rec.truth.poses[we]
    dxy, dyaw = se2.distance_pair(trace.pose, truth[:, None])
    good = (np.asarray(dxy) < CORRECT_XY) & (np.rad2deg(np.asarray(dyaw)) < CORRECT_YAW_DEG)
    last = np.array([len(we) - 1 for we in ends])
    final = good[np.arange(len(recs)), :, last]
    c = commits(trace, 0.5, 10.0)
    mask = np.broadcast_to(trace.window_mask[:, None], c.shape)
    return dict(
        final_correct=float(final.mean()),
        coverage=float(c[mask].mean()),
        risk=float((c & ~good)[mask].sum() / max(1, c[mask].sum())),
    )


def main(argv=None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--particles", type=int, nargs="+", default=[4096, 8192, 16384])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument(
        "--crop",
        nargs="+",
        default=["none", "10"],
        help="scan crop radii (m) to run; 'none' keeps the LiDAR's full range",
    )
    ap.add_argument("--out", default="results/bench_mcl.csv")
    args = ap.parse_args(argv)
    recs, ends = _runs()
    rows = []
    for crop in [None if c == "none" else float(c) for c in args.crop]:
        batch = prepare_mcl_inputs(recs, ends, max_points=60, crop_radius=crop)
        batch = jax.tree.map(jax.numpy.asarray, batch)
        for n in args.particles:
            rows.append(_bench(batch, recs, ends, n, crop, args.reps))
            print(pd.DataFrame(rows[-1:]).to_string(index=False, float_format="%.3f"), flush=True)
    df = pd.DataFrame(rows)
    print(df.to_string(index=False, float_format="%.3f"))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    return df


def _bench(batch, recs, ends, n, crop, reps) -> dict:
    """Compile, first-call and median run times and accuracy for ``n`` particles."""
    params = dataclasses.replace(MCLParams(), n_particles=n)
    run = make_mcl(params)
    jax.clear_caches()
    t0 = time.perf_counter()
    run.lower(batch, FILTER_SEEDS).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    trace = run(batch, FILTER_SEEDS)
    first = time.perf_counter() - t0
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        run(batch, FILTER_SEEDS)
        times.append(time.perf_counter() - t0)
    med = float(np.median(times))
    steps = int(np.asarray(batch.step_mask).sum())
    return dict(
        particles=n,
        beams=params.n_beams,
        crop_m=crop,
        runs=len(recs),
        seeds=len(FILTER_SEEDS),
        steps=steps,
        padded_steps=int(batch.step_mask.size),
        compile_s=compile_s,
        first_call_s=first,
        run_s=med,
        ms_per_step=1e3 * med / (steps * len(FILTER_SEEDS)),
        s_per_run_seed=med / (len(recs) * len(FILTER_SEEDS)),
        **_accuracy(trace, recs, ends),
        device=jax.default_backend(),
    )


if __name__ == "__main__":
    main()
