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
import math
import time
from functools import partial
from pathlib import Path

import jax
import matplotlib
import numpy as np
import pandas as pd

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from mfcl_jax import se2  # noqa: E402
from mfcl_jax import windows as W  # noqa: E402
from mfcl_jax.frontend import (  # noqa: E402
    FrontendParams,
    build_features,
    common_features,
    features,
    hough,
    sanitize_submaps,
)
from mfcl_jax.frontend.driver import FrontEnd  # noqa: E402
from mfcl_jax.frontend.params import COMPILER_OPTIONS  # noqa: E402
from mfcl_jax.frontend.registration import STAGES, register_debug, register_stages  # noqa: E402
from mfcl_jax.sim.scenes import get_scene  # noqa: E402
from mfcl_jax.sources.simulated import simulate  # noqa: E402
from mfcl_jax.windows.arrays import SubmapBatch, pad_submaps  # noqa: E402

SCENES = ("three_rooms", "symmetric_bays")
D_S = (5.0, 6.0, 7.0)
HIT_XY, HIT_DEG = 0.5, 2.0
TIE = 1e-3  # score difference under which two candidates are tied
P_STUDY = 2048  # the study's point bucket (windows.pack of 10 seeds x 3 d_s)
CHUNK = 32  # the study's driver chunk (study.pipeline.register_all)
OPTS = dict(compiler_options=COMPILER_OPTIONS)  # as every front-end call is compiled


def load() -> str:
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def scene_data(seeds) -> dict:
    """``{(scene, d_s): (SubmapBatch, Y (n, 3))}`` over every trajectory of each scene."""
    out = {}
    for name in SCENES:
        recs = simulate(name, seeds=seeds)
        for d_s in D_S:
            items, Y = [], []
            for r in recs:
                w = W.cut(r.seq, W.WindowParams(d_s=d_s))
                items.append((r.seq, w, 0))
                Y.append(np.asarray(r.truth.poses)[w.last_scan()])
            sub = sanitize_submaps(W.pack(items).submaps)
            out[name, d_s] = (sub, np.concatenate(Y).astype(np.float32))
    return out


def rows_of(b: SubmapBatch, idx) -> SubmapBatch:
    return jax.tree.map(lambda a: np.asarray(a)[idx], b)


def metrics(c, dbg, Y) -> dict:
    """Accuracy metrics of one (scene, d_s) from ``register_debug`` outputs (NumPy)."""
    n = len(Y)
    dxy, dth = (np.asarray(a) for a in se2.distance_pair(c.pose, Y[:, None]))
    hit = (dxy < HIT_XY) & (dth < np.radians(HIT_DEG)) & c.mask
    found = hit.any(1)
    rank = np.where(found, hit.argmax(1), -1)
    wrong = ~hit[:, 0] & c.mask[:, 0]
    tied = c.mask & (c.score >= c.score[:, :1] - TIE)
    d_top = np.asarray(se2.distance_pair(c.pose, c.pose[:, :1])[0])
    tie = (tied & (d_top >= HIT_XY)).any(1)
    d_alias = dxy[:, 0][wrong]
    walls = dbg["walls"].astype(bool)
    # Refinement: same candidate before and after.
    d0, t0 = (np.asarray(a) for a in se2.distance_pair(dbg["pose0"], Y[:, None]))
    d1, t1 = (np.asarray(a) for a in se2.distance_pair(dbg["refined"], Y[:, None]))
    k = np.argmin(np.where(dbg["ok0"], d0 + np.degrees(t0) * 0.1, np.inf), 1)
    r = np.arange(n)
    near = d0[r, k] < HIT_XY
    e0, e1 = d0[r, k][near], d1[r, k][near]
    a0, a1 = np.degrees(t0[r, k][near]), np.degrees(t1[r, k][near])
    moved = np.any(dbg["refined"] != dbg["pose0"], -1) & dbg["ok0"]
    q = lambda a, pct: float(np.percentile(a, pct)) if len(a) else np.nan  # noqa: E731
    bay, room = (d_alias >= 5.5) & (d_alias < 9), (d_alias >= 12.5) & (d_alias < 16.5)
    binned = (d_alias < 3) | bay | room
    return (
        dict(
            n_submaps=n,
            recall_at_J=found.mean(),
            top1=hit[:, 0].mean(),
            top1_tied=(hit & tied).any(1).mean(),
            tie_share=tie.mean(),
            share_2walls=walls.mean(),
            top1_2walls=hit[walls, 0].mean() if walls.any() else np.nan,
            share_corner=(dbg["n_corners"] >= 1).mean(),
            alias_share=wrong.mean(),
            alias_lt3m=(d_alias < 3).sum() / n,
            alias_5to9m=bay.sum() / n,
            alias_12to17m=room.sum() / n,
            alias_other=wrong.mean() - binned.sum() / n,
            alias_median_m=float(np.median(d_alias)) if len(d_alias) else np.nan,
            median_rank=float(np.median(rank[found])) if found.any() else np.nan,
            max_rank=int(rank.max()),
            empty=int((~c.mask.any(1)).sum()),
            refine_accepted=moved.sum() / max(dbg["ok0"].sum(), 1),
            err_before_m=q(e0, 50),
            err_before_p90_m=q(e0, 90),
            err_after_m=q(e1, 50),
            err_after_p90_m=q(e1, 90),
            err_before_deg=q(a0, 50),
            err_before_p90_deg=q(a0, 90),
            err_after_deg=q(a1, 50),
            err_after_p90_deg=q(a1, 90),
        ),
        found,
        dxy[:, 0],
        np.degrees(dth[:, 0]),
    )


def diagnose(b, Y, feats, p, rows):
    """Prints, for missed submaps: lines, corners, votes, the vote nearest the truth."""
    for i in rows:
        pts, org, ok, _ = features.subsample(b.points[i], b.origins[i], b.mask[i], p.hough_points)
        lines = features.detect_lines(pts, org, ok, p)
        corners = features.detect_corners(lines, ok, p)
        votes, w = hough.corner_votes(corners, feats.plan_corners, p)
        dxy, dth = (np.asarray(a) for a in se2.distance_pair(votes, np.float32(Y[i])))
        v = np.asarray(w) > 0
        j = np.argmin(np.where(v, dxy + 0.2 * np.degrees(dth), np.inf))
        print(
            f"    miss row {i}: {int(b.mask[i].sum())} pts, {int(lines['valid'].sum())} lines, "
            f"{int(corners['valid'].sum())} corners, {int(v.sum())} votes, nearest vote "
            f"{dxy[j]:.2f} m / {np.degrees(dth[j]):.1f} deg",
            flush=True,
        )


# Flops per field lookup, counted in verify.sample_xy / verify.score / refine._grad_normal
# (the exp as its ~15-flop polynomial): transform 8, cell index 10, bilinear 9, then for an
# occupied point the kernel and the sum (21), for a free-space sample the sum (1), for a
# refinement point the gradient, the heading column, the kernel and nine products and sums (56).
FLOPS = dict(occupied=48, free=28, refine=83)
CORE_GHZ, LOADS_PER_CYCLE, FLOPS_PER_CYCLE = 2.6, 2, 64  # this machine: AVX-512, 2 FMA ports


def work(p: FrontendParams) -> dict:
    """Static work per submap (fixed by the capacities, not by the data): bilinear field
    lookups and their flops per stage, and the pairwise tests of the pose accumulator."""
    look = dict(
        prescreen=(p.n_prescreen, p.prescreen_points),
        score=(p.n_hough, p.verify_points),
        rescore=(p.J, p.verify_points),
    )
    out = {k: k_ * n * (1 + p.ray_samples) for k, (k_, n) in look.items()}
    flops = {
        k: k_ * n * (FLOPS["occupied"] + p.ray_samples * FLOPS["free"])
        for k, (k_, n) in look.items()
    }
    out["refine"] = p.J * p.refine_steps * p.refine_points
    flops["refine"] = out["refine"] * FLOPS["refine"]
    out["flops"] = flops
    out["peaks"] = 2 * p.max_votes**2 + p.n_prescreen * p.max_votes
    return out


def stage_profile(p, sub, feats, reps, rows):
    """Stage table: every pipeline prefix on the same chunks, interleaved repetitions."""
    chunks = [
        pad_submaps(rows_of(sub, slice(a, a + CHUNK)), n=CHUNK, p=P_STUDY)
        for a in range(0, sub.n, CHUNK)
    ]
    fns = {}
    for name in STAGES:
        fn = jax.jit(partial(register_stages, params=p, stop=name), **OPTS)
        t0 = time.perf_counter()
        fns[name] = fn.lower(chunks[0], feats).compile()
        print(f"  compiled prefix ..{name} in {time.perf_counter() - t0:.1f} s", flush=True)
    T = np.zeros((reps, len(STAGES)))
    for r in range(reps):
        for k, name in enumerate(STAGES):
            t0 = time.perf_counter()
            for c in chunks:
                jax.block_until_ready(fns[name](c, feats))
            T[r, k] = 1e3 * (time.perf_counter() - t0) / sub.n
    inc = np.median(np.diff(T, axis=1, prepend=0.0), axis=0)
    cum = np.median(T, axis=0)
    for k, name in enumerate(STAGES):
        rows.append(
            dict(
                kind="stage",
                stage=name,
                P=P_STUDY,
                chunk=CHUNK,
                ms_per_submap=inc[k],
                ms_cumulative=cum[k],
                n_submaps=sub.n,
                repeats=reps,
                load=load(),
            )
        )
    return dict(zip(STAGES, inc, strict=True)), cum[-1]


def driver_rows(p, fps, subs, chunk_sizes, reps, rows):
    """``FrontEnd.register`` on every benchmark submap, per chunk size (compile apart)."""
    sub = jax.tree.map(lambda *a: np.concatenate(a), *[pad_submaps(s, p=P_STUDY) for s, _ in subs])
    building = np.concatenate([np.full(s.n, b) for s, b in subs])
    for c in chunk_sizes:
        fe = FrontEnd(fps, p, chunk=c)
        fe.register(sub, building)  # compiles (one bucket for both scenes)
        ts = []
        for _ in range(reps):
            r0 = fe.run_s
            fe.register(sub, building)
            ts.append(1e3 * (fe.run_s - r0) / sub.n)
        rows.append(
            dict(
                kind="driver",
                stage="all",
                P=P_STUDY,
                chunk=c,
                ms_per_submap=float(np.median(ts)),
                compile_s=fe.compile_s,
                n_submaps=sub.n,
                repeats=reps,
                load=load(),
            )
        )
        print({k: v for k, v in rows[-1].items()}, flush=True)


def area_rows(p, fp, sub, reps, rows):
    """The full pipeline with the plan padded to a larger raster (cost vs floor area)."""
    r = fp.rasterize(0.10)
    chunks = [
        pad_submaps(rows_of(sub, slice(a, a + CHUNK)), n=CHUNK, p=P_STUDY)
        for a in range(0, sub.n, CHUNK)
    ]
    fn = jax.jit(partial(register_stages, params=p, stop=STAGES[-1]), **OPTS)
    for ax in (1, 4):
        s = math.sqrt(ax)
        shape = (int(np.ceil(r.shape[0] * s)), int(np.ceil(r.shape[1] * s)))
        f = build_features(fp, p, rasters=r, shape=shape, corner_capacity=64 * ax)
        jax.block_until_ready(fn(chunks[0], f))
        ts = []
        for _ in range(reps):
            t0 = time.perf_counter()
            for c in chunks:
                jax.block_until_ready(fn(c, f))
            ts.append(1e3 * (time.perf_counter() - t0) / sub.n)
        rows.append(
            dict(
                kind="area",
                stage="all",
                P=P_STUDY,
                chunk=CHUNK,
                area_x=ax,
                ms_per_submap=float(np.median(ts)),
                n_submaps=sub.n,
                repeats=reps,
                load=load(),
            )
        )
        print({k: v for k, v in rows[-1].items()}, flush=True)


def roofline(p, inc) -> str:
    """One sentence: the dominant kernel's work per submap against two cores' capacity."""
    w = work(p)
    look = ("prescreen", "score", "refine", "rescore")
    n_look = sum(w[k] for k in look)
    flops = sum(w["flops"][k] for k in look)
    t_look = sum(inc[k] for k in look)
    # One lookup reads one 16-byte cell (stack4 layout): one vector load for hand-written code.
    load_ms = 1e3 * n_look / (2 * CORE_GHZ * 1e9 * LOADS_PER_CYCLE)
    flop_ms = 1e3 * flops / (2 * CORE_GHZ * 1e9 * FLOPS_PER_CYCLE)
    bound = max(load_ms, flop_ms)
    share = 100 * t_look / sum(inc.values())
    return (
        f"field lookups (prescreen + score + refine + rescore, {share:.0f}% of the time): "
        f"{n_look / 1e3:.0f} k per submap, {16 * n_look / 1e6:.1f} MB of "
        f"16-byte cells and {flops / 1e6:.0f} MFLOP; measured {t_look:.2f} ms = "
        f"{1e6 * t_look / n_look:.1f} ns per lookup. Two cores ({CORE_GHZ} GHz, "
        f"{LOADS_PER_CYCLE} loads and {FLOPS_PER_CYCLE} flop per cycle each) would issue the "
        f"loads in {load_ms:.3f} ms and the flops in {flop_ms:.3f} ms: {t_look / bound:.0f}x "
        f"away, because XLA:CPU runs the batch on one core and gathers one scalar at a time "
        f"(four per lookup) from cells scattered over the plan. Pose accumulator: at most "
        f"{w['peaks'] / 1e3:.0f} k pairwise window tests per submap (the tables run on the "
        f"smallest of {p.max_votes // 4}, {p.max_votes // 2}, {p.max_votes} votes that holds "
        f"the valid ones; most submaps cast about 100) in {inc['peaks']:.2f} ms. Dense "
        f"hypotheses (one FFT correlation per distinct heading over the plan, then "
        f"{p.dense_n} polished peaks): {inc['dense']:.2f} ms, "
        f"{100 * inc['dense'] / sum(inc.values()):.0f}% of the time."
    )


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


def figure(df, ed, tdf, p, path):
    fig, ax = plt.subplots(1, 4, figsize=(21, 4.2))
    for name, g in ed.groupby("scene"):
        ax[0].hist(
            np.clip(g.top1_err_m, 1e-3, 30), bins=np.geomspace(1e-3, 30, 60), alpha=0.6, label=name
        )
    for x, lab in ((7.3, "bay 7.3 m"), (14.4, "room 14.4 m")):
        ax[0].axvline(x, color="k", ls=":", lw=0.8)
        ax[0].text(x, ax[0].get_ylim()[1] * 0.9, lab, rotation=90, fontsize=7, ha="right")
    ax[0].set_xscale("log")
    ax[0].set_xlabel("top-1 position error (m)")
    ax[0].set_ylabel("submaps")
    ax[0].legend(fontsize=8)
    for name, g in df.groupby("scene"):
        ax[1].plot(g.d_s, g.recall_at_J, "o-", label=f"{name} recall@{p.J}")
        ax[1].plot(g.d_s, g.top1, "s--", label=f"{name} top-1")
    ax[1].axhline(0.95, color="k", ls=":", lw=0.8)
    ax[1].set_xlabel("d_s (m)")
    ax[1].set_ylim(0, 1.05)
    ax[1].legend(fontsize=8)
    x = np.arange(len(df))
    lab = [f"{s[:5]} {d:g}" for s, d in zip(df.scene, df.d_s, strict=True)]
    ax[2].bar(x - 0.2, 100 * df.err_before_m, 0.4, label="before refinement (median)")
    ax[2].bar(x + 0.2, 100 * df.err_after_m, 0.4, label="after (same candidate)")
    ax[2].errorbar(x - 0.2, 100 * df.err_before_p90_m, fmt="k_", label="90th pct")
    ax[2].errorbar(x + 0.2, 100 * df.err_after_p90_m, fmt="k_")
    ax[2].set_xticks(x, lab, rotation=30, fontsize=8)
    ax[2].set_ylabel("position error of the true candidate (cm)")
    ax[2].legend(fontsize=8)
    st = tdf[tdf.kind == "stage"]
    ax[3].barh(st.stage, st.ms_per_submap)
    ax[3].invert_yaxis()
    total = st.ms_cumulative.max()
    ax[3].set_xlabel(f"ms per submap (chunk {CHUNK}, P {P_STUDY}; total {total:.1f})")
    ax[3].set_title("stage profile (one run, interleaved medians)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--quick", action="store_true", help="fewer timing variants and repeats")
    a = ap.parse_args()
    main(tuple(a.seeds), quick=a.quick)
