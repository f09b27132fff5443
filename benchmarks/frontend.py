"""Front-end benchmark on simulator data: recall@J, top-1, alias share, refinement, timing.

Usage: python benchmarks/frontend.py [--seeds 0 1]
Writes results/frontend.csv (one row per scene x d_s) and results/frontend.png.
"""

from __future__ import annotations

import argparse
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
from mfcl_jax.batch import SubmapBatch  # noqa: E402
from mfcl_jax.floorplan.scenes import get_scene  # noqa: E402
from mfcl_jax.frontend import FrontendParams, build_features, sanitize_submaps  # noqa: E402
from mfcl_jax.frontend.registry import register_debug  # noqa: E402
from mfcl_jax.sim import simulate  # noqa: E402


def _row(b: SubmapBatch, i: int) -> SubmapBatch:
    return jax.tree.map(lambda a: np.asarray(a)[i : i + 1], b)


def main(seeds=(0,), out=Path("results")):
    p = FrontendParams()
    fn = jax.jit(partial(register_debug, params=p))
    rows, errs = [], []
    for name in ("three_rooms", "symmetric_bays"):
        fp = get_scene(name).floorplan
        feats = build_features(fp, p)
        area = float(fp.footprint.area)
        for d_s in (5.0, 6.0, 7.0):
            sim = simulate(name, d_s_values=(d_s,), seeds=tuple(seeds))
            b = sanitize_submaps(sim.submaps)
            t0 = time.perf_counter()
            c, pose0 = jax.block_until_ready(fn(b, feats))
            t_first = time.perf_counter() - t0
            ts = []
            for _ in range(3):
                t0 = time.perf_counter()
                jax.block_until_ready(fn(b, feats))
                ts.append(time.perf_counter() - t0)
            ms_batched = 1e3 * np.median(ts) / b.n
            one = _row(b, 0)
            t0 = time.perf_counter()
            jax.block_until_ready(fn(one, feats))
            compile_one = time.perf_counter() - t0
            t1 = []
            for i in range(min(b.n, 10)):
                r = _row(b, i)
                t0 = time.perf_counter()
                jax.block_until_ready(fn(r, feats))
                t1.append(time.perf_counter() - t0)
            Y = np.asarray(sim.truth.Y)
            pose, mask = np.asarray(c.pose), np.asarray(c.mask)
            dxy, dth = (np.asarray(a) for a in se2.distance_pair(pose, Y[:, None]))
            hit = (dxy < 0.5) & (dth < np.radians(2)) & mask
            rank = np.where(hit.any(1), hit.argmax(1), -1)
            d0xy, d0th = (np.asarray(a) for a in se2.distance_pair(np.asarray(pose0), Y[:, None]))
            # Pose error of the true candidate before (voted) and after refinement.
            j = np.argmin(np.where(hit, dxy, np.inf), 1)
            k = np.argmin(np.where(mask, d0xy + 10 * d0th, np.inf), 1)
            ok = hit.any(1)
            e_after = dxy[np.arange(b.n), j][ok]
            e_before = d0xy[np.arange(b.n), k][ok]
            top1_err = np.where(mask[:, 0], dxy[:, 0], np.nan)
            for e, t in zip(top1_err, np.degrees(dth[:, 0]), strict=True):
                errs.append(dict(scene=name, d_s=d_s, top1_err_m=e, top1_err_deg=t))
            wrong = ~hit[:, 0] & mask[:, 0]
            rows.append(dict(
                scene=name, d_s=d_s, n_submaps=b.n, P=b.points.shape[1], area_m2=area,
                recall_at_J=ok.mean(), J=p.J, top1=hit[:, 0].mean(),
                alias_share=wrong.mean(),
                alias_far_share=(wrong & (dxy[:, 0] > 3.0)).mean(),
                median_rank=float(np.median(rank[ok])) if ok.any() else np.nan,
                max_rank=int(rank.max()),
                empty=int((~mask.any(1)).sum()),
                err_before_m=float(np.median(e_before)), err_after_m=float(np.median(e_after)),
                ms_per_submap_batched=ms_batched, ms_per_submap_single=1e3 * np.median(t1),
                compile_s_batch=t_first, compile_s_single=compile_one,
            ))
            print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "frontend.csv", index=False)
    ed = pd.DataFrame(errs)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for name, g in ed.groupby("scene"):
        ax[0].hist(np.clip(g.top1_err_m, 0, 30), bins=60, alpha=0.6, label=name)
    ax[0].set_xlabel("top-1 position error (m), clipped at 30")
    ax[0].set_ylabel("submaps")
    ax[0].set_yscale("log")
    ax[0].legend()
    for name, g in df.groupby("scene"):
        ax[1].plot(g.d_s, g.recall_at_J, "o-", label=f"{name} recall@{p.J}")
        ax[1].plot(g.d_s, g.top1, "s--", label=f"{name} top-1")
    ax[1].set_xlabel("d_s (m)")
    ax[1].set_ylim(0, 1.05)
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "frontend.png", dpi=120)
    return df


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    main(tuple(ap.parse_args().seeds))
