"""Front-end benchmark on simulator data: recall@J, top-1, aliases, refinement, timing.

Usage: python benchmarks/frontend.py [--seeds 0 1] [--quick]
Writes results/frontend.csv (one row per scene x d_s), results/frontend_timing.csv (timing vs
batch mode, floor area, point capacity; per-stage profile; three_rooms d_s = 5 m) and
results/frontend.png.

All scenes and window lengths go through ONE compilation: the plans share a raster bucket
(``common_features``) and the submap batches are padded to one (N, P) bucket on the host.

Definitions:
- hit: a returned candidate within 0.5 m and 2 deg of the true ``^B T_S``.
- recall@J: share of submaps with a hit among their J candidates; top-1: the first is a hit.
- two_walls: the submap shows two detected lines with >= 30 inliers each (of the 768-point
  Hough subsample) crossing at >= 30 deg; top1_2walls is top-1 over those submaps.
- alias: a top-1 candidate that is not a hit; its distance to the truth is binned
  (< 3 m, 5.5-9 m: one bay pitch 7.3 m, 12.5-16.5 m: one room 14.4 m or two bays 14.6 m).
- refinement: for the verified candidate nearest the truth before refinement (and within
  0.5 m), its position / heading error before and after refinement (same candidate).
"""

from __future__ import annotations

import argparse
import subprocess
import time
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib
import numpy as np
import pandas as pd

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from mfcl_jax import se2  # noqa: E402
from mfcl_jax.batch import SubmapBatch  # noqa: E402
from mfcl_jax.floorplan.scenes import get_scene  # noqa: E402
from mfcl_jax.frontend import (  # noqa: E402
    FrontendParams,
    build_features,
    common_features,
    features,
    hough,
    refine,
    sanitize_submaps,
    verify,
)
from mfcl_jax.frontend.registry import register, register_debug  # noqa: E402
from mfcl_jax.sim import simulate  # noqa: E402

SCENES = ("three_rooms", "symmetric_bays")
D_S = (5.0, 6.0, 7.0)
HIT_XY, HIT_DEG = 0.5, 2.0


def load() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def pad_batch(b: SubmapBatch, n: int, P: int) -> SubmapBatch:
    """Host: pads a batch to ``n`` submaps (empty) and ``P`` points per submap."""
    if P < b.points.shape[1] and np.asarray(b.mask)[:, P:].any():
        raise ValueError(f"pad_batch: submaps hold more than {P=} points")
    b = jax.tree.map(lambda a: np.asarray(a)[:, :P] if np.ndim(a) >= 2 else np.asarray(a), b)

    def pad(a, fill=0):
        a = np.asarray(a)
        out = np.full((n, *((P,) if a.ndim >= 2 else ()), *a.shape[2:]), fill, a.dtype)
        out[tuple(slice(0, s) for s in a.shape[:2])] = a
        return out

    return SubmapBatch(
        points=pad(b.points),
        origins=pad(b.origins),
        mask=pad(b.mask, False),
        X=np.concatenate([np.asarray(b.X), np.zeros((n - b.n, 3), np.float32)]),
        run=pad(b.run),
        window=pad(b.window),
        t=pad(b.t),
        n_dropped=pad(b.n_dropped),
    )


def timed(fn, *args, repeats=5) -> float:
    """Median seconds of ``repeats`` calls (the caller compiled ``fn`` already)."""
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def metrics(c, dbg, Y) -> dict:
    """Accuracy metrics of one (scene, d_s) from ``register_debug`` outputs (NumPy)."""
    n = len(Y)
    dxy, dth = (np.asarray(a) for a in se2.distance_pair(c.pose, Y[:, None]))
    hit = (dxy < HIT_XY) & (dth < np.radians(HIT_DEG)) & c.mask
    found = hit.any(1)
    rank = np.where(found, hit.argmax(1), -1)
    wrong = ~hit[:, 0] & c.mask[:, 0]
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
    return (
        dict(
            n_submaps=n,
            recall_at_J=found.mean(),
            top1=hit[:, 0].mean(),
            share_2walls=walls.mean(),
            top1_2walls=hit[walls, 0].mean() if walls.any() else np.nan,
            share_corner=(dbg["n_corners"] >= 1).mean(),
            alias_share=wrong.mean(),
            alias_lt3m=(d_alias < 3).sum() / n,
            alias_5to9m=((d_alias >= 5.5) & (d_alias < 9)).sum() / n,
            alias_12to17m=((d_alias >= 12.5) & (d_alias < 16.5)).sum() / n,
            alias_other=wrong.mean()
            - (
                (d_alias < 3)
                | ((d_alias >= 5.5) & (d_alias < 9))
                | ((d_alias >= 12.5) & (d_alias < 16.5))
            ).sum()
            / n,
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
        plan = feats.plan_corners
        votes, w = hough.corner_votes(corners, plan, p)
        dxy, dth = (np.asarray(a) for a in se2.distance_pair(votes, np.float32(Y[i])))
        v = np.asarray(w) > 0
        j = np.argmin(np.where(v, dxy + 0.2 * np.degrees(dth), np.inf))
        print(
            f"    miss row {i}: {int(b.mask[i].sum())} pts, {int(lines['valid'].sum())} lines, "
            f"{int(corners['valid'].sum())} corners, {int(v.sum())} votes, nearest vote "
            f"{dxy[j]:.2f} m / {np.degrees(dth[j]):.1f} deg",
            flush=True,
        )


def stage_fn(k, p):
    """Pipeline prefix ``k`` (0 lines, 1 corners, 2 votes+accumulator, 3 prescreen+verify,
    4 refine, 5 re-score) for the stage profile."""

    def run(points, origins, mask, feats):
        points, origins, mask = features.compact(points, origins, mask)
        sub = partial(features.subsample, points, origins, mask, compacted=True)
        pts, org, ok, _ = sub(p.hough_points)
        lines = features.detect_lines(pts, org, ok, p)
        if k == 0:
            return lines["u"]
        corners = features.detect_corners(lines, ok, p)
        if k == 1:
            return corners["pos"]
        plan = feats.plan_corners
        peaks, _, _, _, _ = hough.vote(*hough.corner_votes(corners, plan, p), p, p.n_prescreen)
        if k == 2:
            return peaks

        def scorer(n):
            vp, vo, vok, _ = sub(n)
            q, q_ok = verify.free_samples(vp, vo, vok, p.ray_samples, p.ray_stop)
            return jax.vmap(
                lambda y: verify.score(y, vp, vok, q, q_ok, feats, p.sigma_occ, p.lambda_free)
            )

        ph = peaks[jnp.argsort(-scorer(p.prescreen_points)(peaks))[: p.n_hough]]
        s = scorer(p.verify_points)(ph)
        if k == 3:
            return s
        rp, _, rok, _ = sub(p.refine_points)
        p1 = refine.refine(ph[jnp.argsort(-s)[: p.J]], rp, rok, feats, p)
        return p1 if k == 4 else scorer(p.verify_points)(p1)

    return jax.jit(jax.vmap(run, in_axes=(0, 0, 0, None)))


def timing(p, fp, b, feats_one, out_rows, quick=False):
    """Timing rows: batched vs single, floor area, point capacity, stage profile."""
    reps = 3 if quick else 5
    N = -(-b.n // 64) * 64
    for P in (1024, 2048) if quick else (1024, 2048, 4096):
        bb = pad_batch(b, N, P)
        fn = jax.jit(partial(register, params=p))
        t0 = time.perf_counter()
        jax.block_until_ready(fn(bb, feats_one))
        comp = time.perf_counter() - t0
        out_rows.append(
            dict(
                kind="points",
                P=P,
                area_x=1,
                mode="batched",
                ms_per_submap=1e3 * timed(fn, bb, feats_one, repeats=reps) / b.n,
                compile_s=comp,
                load=load(),
            )
        )
        print(out_rows[-1], flush=True)
    bb = pad_batch(b, N, 2048)
    ones = [
        pad_batch(jax.tree.map(lambda a, i=i: np.asarray(a)[i : i + 1], b), 1, 2048)
        for i in range(5)
    ]
    fn = jax.jit(partial(register, params=p))
    t0 = time.perf_counter()
    jax.block_until_ready(fn(ones[0], feats_one))
    comp = time.perf_counter() - t0
    ts = [timed(fn, o, feats_one, repeats=reps) for o in ones]
    out_rows.append(
        dict(
            kind="single",
            P=2048,
            area_x=1,
            mode="one at a time",
            ms_per_submap=1e3 * float(np.median(ts)),
            compile_s=comp,
            load=load(),
        )
    )
    print(out_rows[-1], flush=True)
    r = fp.rasterize(0.10)
    for ax in (2, 4):
        s = np.sqrt(ax)
        shape = (int(np.ceil(r.shape[0] * s)), int(np.ceil(r.shape[1] * s)))
        f = build_features(fp, p, rasters=r, shape=shape, corner_capacity=64 * ax)
        fn = jax.jit(partial(register, params=p))
        jax.block_until_ready(fn(bb, f))
        out_rows.append(
            dict(
                kind="area",
                P=2048,
                area_x=ax,
                mode="batched",
                ms_per_submap=1e3 * timed(fn, bb, f, repeats=reps) / b.n,
                compile_s=np.nan,
                load=load(),
            )
        )
        print(out_rows[-1], flush=True)
    prev = 0.0
    names = ("lines", "corners", "votes+accumulator", "prescreen+verify", "refine", "re-score")
    for k, name in enumerate(names):
        fn = stage_fn(k, p)
        args = (bb.points, bb.origins, bb.mask, feats_one)
        jax.block_until_ready(fn(*args))
        ms = 1e3 * timed(fn, *args, repeats=reps) / b.n
        out_rows.append(
            dict(
                kind="stage",
                stage=name,
                P=2048,
                area_x=1,
                mode="batched",
                ms_per_submap=ms - prev,
                ms_cumulative=ms,
                load=load(),
            )
        )
        print(out_rows[-1], flush=True)
        prev = ms


def main(seeds=(0, 1), out=Path("results"), quick=False):
    p = FrontendParams()
    fps = [get_scene(s).floorplan for s in SCENES]
    feats = dict(zip(SCENES, common_features(fps, p), strict=True))
    sims = {(s, d): simulate(s, d_s_values=(d,), seeds=tuple(seeds)) for s in SCENES for d in D_S}
    batches = {k: sanitize_submaps(v.submaps) for k, v in sims.items()}
    N = -(-max(b.n for b in batches.values()) // 64) * 64
    P = max(b.points.shape[1] for b in batches.values())
    fn = jax.jit(partial(register_debug, params=p))
    rows, errs = [], []
    print("load before:", load(), flush=True)
    for (name, d_s), b in batches.items():
        Y = np.asarray(sims[name, d_s].truth.Y)
        bb = pad_batch(b, N, P)
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
                P=P,
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

    trows = []
    fp = get_scene("three_rooms").floorplan
    b = batches["three_rooms", 5.0]  # <= 1024 points each: every capacity bucket holds them
    timing(p, fp, b, build_features(fp, p), trows, quick=quick)
    tdf = pd.DataFrame(trows)
    tdf.to_csv(out / "frontend_timing.csv", index=False)
    figure(df, pd.DataFrame(errs), tdf, p, out / "frontend.png")
    return df, tdf


def figure(df, ed, tdf, p, path):
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.2))
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
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--quick", action="store_true", help="fewer timing variants and repeats")
    a = ap.parse_args()
    main(tuple(a.seeds), quick=a.quick)
