"""Front-end recall on the benchmark's nominal runs: does the evidence contain the truth?

For every window of every nominal run (the benchmark's families, seeds and walks, d_s = 6 m),
the front-end's candidates are compared with the true pose of the window's frame (ground
truth used here only, to score): ``top1`` is the share of windows whose best-scored candidate
is within 1 m and 5 deg of it, ``any`` the share with some candidate there, ``none`` the
share with no candidate at all. Each variant in ``VARIANTS`` registers the same windows (the
same scans, the same window bounds): ``corners only`` without the dense hypotheses,
``input odometry`` with the submaps built on the input odometry as it is (no LiDAR
odometry), ``default`` the front-end and windows as the layer runs them.

``python -m experiments.frontend_recall`` writes ``results/frontend_recall.{csv,md}``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from mfcl_jax import windows as W
from mfcl_jax.bench import suite
from mfcl_jax.bench.config import BenchmarkConfig, validate
from mfcl_jax.frontend.driver import FrontEnd
from mfcl_jax.frontend.params import FrontendParams
from mfcl_jax.score import CORRECT_XY, CORRECT_YAW_DEG, pose_at
from mfcl_jax.se2 import wrap_host
from mfcl_jax.windows import ScanMatchParams

__all__ = ["VARIANTS", "window_hits", "recall_table", "main"]

# name: (FrontendParams overrides, LiDAR odometry on)
VARIANTS = {
    "corners only": (dict(dense_n=0), True),
    "input odometry": ({}, False),
    "default": ({}, True),
}


def window_hits(cands, i: int, Y) -> tuple[int, bool, bool]:
    """``(n candidates, top-1 correct, any correct)`` of submap row ``i`` against pose ``Y``."""
    m = np.asarray(cands.mask[i], bool)
    p, s = np.asarray(cands.pose[i], np.float64)[m], np.asarray(cands.score[i])[m]
    if len(s) == 0:
        return 0, False, False
    e = np.hypot(p[:, 0] - Y[0], p[:, 1] - Y[1])
    dth = np.degrees(np.abs(wrap_host(p[:, 2] - Y[2])))
    ok = (e < CORRECT_XY) & (dth < CORRECT_YAW_DEG)
    return len(s), bool(ok[int(np.argmax(s))]), bool(ok.any())


def recall_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per family and variant (and ``all``): windows, none, top1, any (shares)."""
    agg = dict(windows=("k", "size"), none=("n", lambda x: float(np.mean(x == 0))),
               top1=("top1", "mean"), any=("any", "mean"))  # fmt: skip
    fam = rows.groupby(["family", "variant"], sort=False).agg(**agg).reset_index()
    tot = rows.groupby("variant", sort=False).agg(**agg).reset_index().assign(family="all")
    return pd.concat([fam, tot], ignore_index=True)


def main(out: str = "results", families=None) -> pd.DataFrame:
    cfg = BenchmarkConfig(faults=[], policies=["ours"])
    if families:
        cfg.families = list(families)
    cfg = validate(cfg)
    t0 = time.perf_counter()
    recs = suite.nominal_recordings(cfg)
    plans = {}
    for r in recs:
        plans.setdefault(id(r.floorplan), (len(plans), r.floorplan))
    fps = [fp for _, fp in sorted(plans.values(), key=lambda t: t[0])]
    batches = {}
    for matched in sorted({m for _, m in VARIANTS.values()}):
        wp = W.WindowParams(d_s=cfg.d_s, scan_match=ScanMatchParams(enabled=matched))
        items = [(r.seq, W.cut(r.seq, wp), plans[id(r.floorplan)][0]) for r in recs]
        batches[matched] = W.pack(items, capacity=wp.capacity)
    wb = batches[True]
    print(f"[recall] {len(recs)} runs, {wb.submaps.n} windows ({time.perf_counter() - t0:.0f} s)")
    # Per odometry variant: the jump test of the LiDAR odometry can split a run, so the two
    # variants need not cut the same windows.
    truth = {m: [pose_at(r.truth.times, r.truth.poses, w.t) for r, w in zip(recs, b.windows,
                                                                             strict=True)]
             for m, b in batches.items()}  # fmt: skip
    rows = []
    for name, (kw, matched) in VARIANTS.items():
        wb = batches[matched]
        fe = FrontEnd(fps, FrontendParams(**kw), multiple=256)
        cands = fe.register(wb.submaps, wb.building)
        ms = 1000 * fe.run_s / max(wb.submaps.n, 1)
        print(f"[recall] {name}: {ms:.1f} ms per window (compile {fe.compile_s:.0f} s apart)")
        for j, rec in enumerate(recs):
            sub = np.asarray(wb.runs.submap[j])
            for k in range(len(wb.windows[j])):
                if sub[k] < 0:
                    continue
                n, top, anyc = window_hits(cands, int(sub[k]), truth[matched][j][k])
                rows.append(dict(family=rec.meta.get("family", "?"), run=rec.name, k=k + 1,
                                 variant=name, n=n, top1=top, any=anyc))  # fmt: skip
    tab = recall_table(pd.DataFrame(rows))
    dst = Path(out)
    dst.mkdir(parents=True, exist_ok=True)
    tab.to_csv(dst / "frontend_recall.csv", index=False)
    wide = tab.pivot(index="family", columns="variant", values=["none", "top1", "any"])
    wide = wide.reindex([*dict.fromkeys(tab["family"])])
    wide.columns = [f"{v} {c}" for c, v in wide.columns]
    wide.insert(0, "windows", tab.drop_duplicates("family").set_index("family")["windows"])
    (dst / "frontend_recall.md").write_text(wide.round(2).to_markdown() + "\n")
    print(wide.round(2).to_markdown())
    return tab
