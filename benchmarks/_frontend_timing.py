"""The timing of ``benchmarks/frontend.py``: the stage profile (every pipeline prefix on the
same chunks), the driver per chunk size, the cost against floor area, the static work per
submap and the roofline sentence, and the machine's load recorded with each row."""

from __future__ import annotations

import math
import time
from functools import partial

import jax
import numpy as np

from benchmarks._frontend_data import CHUNK, OPTS, P_STUDY, rows_of
from mfcl_jax.frontend import FrontendParams, build_features
from mfcl_jax.frontend.driver import FrontEnd
from mfcl_jax.frontend.registration import STAGES, register_stages
from mfcl_jax.windows.arrays import pad_submaps


def load() -> str:
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


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
