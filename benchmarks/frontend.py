"""Front-end benchmark on simulator data: recall@J, top-1, aliases, refinement, timing.

Usage: python benchmarks/frontend.py [--seeds 0 1] [--quick]
Writes results/frontend.csv (one row per scene x d_s), results/frontend_timing.csv (stage
profile, driver chunk sizes, single-submap streaming, floor area) and results/frontend.png.

Data: the study's path (``sources.simulated`` -> ``windows.cut`` -> ``windows.pack``) on every
trajectory of the stand-in scenes; the truth of a submap is the true sensor pose at its
window's last scan. All scenes and window lengths go through ONE compilation: the plans share
a raster bucket (``common_features``) and the submaps are padded to one (N, P) bucket.

Definitions:
- hit: a returned candidate within 0.5 m and 2 deg of the true ``^B T_S``.
- recall@J: share of submaps with a hit among their J candidates; top-1: the first is a hit.
- two_walls: the submap shows two detected lines with >= 30 inliers each (of the Hough
  subsample) crossing at >= 30 deg; top1_2walls is top-1 over those submaps.
- tie: a candidate >= 0.5 m from the top-1 scoring within ``TIE`` (1e-3) of it; the order of
  tied candidates is decided by rounding (the bays and rooms of the scenes are symmetric), so
  top1_tied (a hit among the candidates tied with the best) is the rounding-free top-1.
- alias: a top-1 candidate that is not a hit; its distance to the truth is binned
  (< 3 m, 5.5-9 m: one bay pitch 7.3 m, 12.5-16.5 m: one room 14.4 m or two bays 14.6 m).
- refinement: for the verified candidate nearest the truth before refinement (and within
  0.5 m), its position / heading error before and after refinement (same candidate).

Timing (all in this one process, compile time apart, medians of interleaved repetitions):
- stage: the pipeline cut after each stage (``registration.register_stages``), every prefix run
  on the same chunks in turn within each repetition; ``ms_per_submap`` is the median over
  repetitions of the difference to the previous prefix in the same repetition.
- driver: ``FrontEnd.register`` (host padding included) on every benchmark submap, per chunk
  size; chunk 1 is the streaming robot.
- area: the full pipeline with the plan padded to a 2x / 4x larger raster bucket.
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path

import jax
import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._frontend_accuracy import diagnose, metrics  # noqa: E402
from benchmarks._frontend_data import (  # noqa: E402
    CHUNK,
    D_S,
    OPTS,
    P_STUDY,
    SCENES,
    rows_of,
    scene_data,
)
from benchmarks._frontend_figure import figure  # noqa: E402
from benchmarks._frontend_timing import (  # noqa: E402
    area_rows,
    driver_rows,
    load,
    roofline,
    stage_profile,
)
from mfcl_jax.frontend import FrontendParams, common_features  # noqa: E402
from mfcl_jax.frontend.registration import register_debug  # noqa: E402
from mfcl_jax.sim.scenes import get_scene  # noqa: E402
from mfcl_jax.windows.arrays import pad_submaps  # noqa: E402


def main(seeds=(0, 1), out=Path("results"), quick=False):
    p = FrontendParams()
    fps = [get_scene(s).floorplan for s in SCENES]
    feats = dict(zip(SCENES, common_features(fps, p), strict=True))
    print("load before:", load(), flush=True)
    data = scene_data(seeds)
    N = -(-max(b.n for b, _ in data.values()) // 64) * 64
    fn = jax.jit(partial(register_debug, params=p), **OPTS)
    rows, errs = [], []
    for (name, d_s), (b, Y) in data.items():
        bb = pad_submaps(b, n=N, p=P_STUDY)
        t0 = time.perf_counter()
        c, dbg = jax.block_until_ready(fn(bb, feats[name]))
        t_first = time.perf_counter() - t0
        c, dbg = jax.tree.map(lambda a, n=b.n: np.asarray(a)[:n], (c, dbg))
        m, found, e_xy, e_deg = metrics(c, dbg, Y)
        rows.append(
            dict(
                scene=name,
                d_s=d_s,
                seeds=" ".join(map(str, seeds)),
                P=P_STUDY,
                J=p.J,
                area_m2=float(get_scene(name).floorplan.footprint.area),
                **m,
                first_call_s=t_first,
            )
        )
        print(
            {k: (round(v, 4) if isinstance(v, float) else v) for k, v in rows[-1].items()},
            flush=True,
        )
        if not found.all():
            diagnose(b, Y, feats[name], p, np.flatnonzero(~found))
        errs += [
            dict(scene=name, d_s=d_s, top1_err_m=e, top1_err_deg=t)
            for e, t, ok in zip(e_xy, e_deg, c.mask[:, 0], strict=True)
            if ok
        ]
    df = pd.DataFrame(rows)
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "frontend.csv", index=False)

    reps = 5 if quick else 7
    trows = []
    # Stage profile on 128 three_rooms submaps drawn over all window lengths.
    pool = [data["three_rooms", d] for d in D_S]
    tr = jax.tree.map(lambda *a: np.concatenate(a), *[pad_submaps(b, p=P_STUDY) for b, _ in pool])
    pick = np.sort(np.random.default_rng(0).permutation(tr.n)[: 4 * CHUNK])
    stage_sub = rows_of(tr, pick)
    print("stage profile:", flush=True)
    inc, total = stage_profile(p, stage_sub, feats["three_rooms"], reps, trows)
    for row in trows:
        print(f"  {row['stage']:10s} {row['ms_per_submap']:6.2f} ms/submap", flush=True)
    print(f"  {'total':10s} {total:6.2f} ms/submap  (load {load()})", flush=True)
    subs = [(b, SCENES.index(s)) for (s, _), (b, _) in data.items()]
    driver_rows(p, fps, subs, (1, CHUNK) if quick else (1, 16, CHUNK, 64), 3, trows)
    if not quick:
        area_rows(p, fps[0], stage_sub, reps, trows)
    sentence = roofline(p, inc)
    print("roofline:", sentence, flush=True)
    trows.append(dict(kind="roofline", stage=sentence, load=load()))
    tdf = pd.DataFrame(trows)
    # the roofline row leaves them empty; --quick writes no area rows (no area_x)
    ints = [c for c in ("P", "chunk", "n_submaps", "repeats", "area_x") if c in tdf]
    tdf[ints] = tdf[ints].astype("Int64")
    tdf.to_csv(out / "frontend_timing.csv", index=False)
    figure(df, pd.DataFrame(errs), tdf, p, out / "frontend.png")
    return df, tdf


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--quick", action="store_true", help="fewer timing variants and repeats")
    a = ap.parse_args()
    main(tuple(a.seeds), quick=a.quick)
