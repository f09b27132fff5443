"""LiDAR odometry benchmark: accuracy inside windows and cost per keyframe.

Usage: python benchmarks/scanmatch.py [--families bag:intel log:intel ...]
Writes results/bench_scanmatch.csv (one row per family x odometry) and
results/bench_scanmatch.png (window heading-error distributions, input vs matched).

Data: the benchmark's nominal runs of the families named (default: the raw Intel bag, the
four logs and three simulated families; ``bench.suite.nominal_recordings``). For every window
(``d_s = 6 m``, 2 m step, bounds from the input odometry) the relative pose error between its
first and last keyframe against the truth, which is what bends a submap, for the input
odometry and the matched one; ground truth is read here only, to score. Timing:
``Odometer.extend`` over each run's keyframes after one warm-up call (compilation apart);
median over runs of ms per keyframe.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from mfcl_jax import se2  # noqa: E402
from mfcl_jax import windows as W  # noqa: E402
from mfcl_jax.bench import suite  # noqa: E402
from mfcl_jax.bench.config import BenchmarkConfig, validate  # noqa: E402
from mfcl_jax.score import pose_at  # noqa: E402
from mfcl_jax.windows.odometry import Odometer  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "results"
FAMILIES = ["bag:intel", "log:intel", "log:freiburg-101", "log:orebro", "log:seattle",
            "corridor", "hall", "offices"]  # fmt: skip


def window_errors(bounds, odo, truth) -> tuple[np.ndarray, np.ndarray]:
    """Per window: translation (m) and heading (deg) error of its first-to-last motion."""
    a, b = bounds[:, 0], bounds[:, 1]
    rel_t = se2.compose_host(se2.inverse_host(truth[a]), truth[b])
    rel_o = se2.compose_host(se2.inverse_host(odo[a]), odo[b])
    d = se2.compose_host(se2.inverse_host(rel_t), rel_o)
    return np.hypot(d[:, 0], d[:, 1]), np.degrees(np.abs(d[:, 2]))


def main(argv=None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", nargs="+", default=FAMILIES)
    a = ap.parse_args(argv)
    cfg = BenchmarkConfig(faults=[], policies=["ours"])
    cfg.families = list(a.families)
    recs = suite.nominal_recordings(validate(cfg))
    wp = W.WindowParams()
    t0 = time.perf_counter()
    Odometer().extend([np.zeros((4, 2))] * 2, np.zeros((2, 3)), np.zeros(2, int))
    print(f"[scanmatch] compile {time.perf_counter() - t0:.1f} s")
    errs, ms = [], []
    for rec in recs:
        kf = W.keyframes(rec.seq.odometry, wp.keyframe_spacing, wp.keyframe_turn_deg)
        raw, t = rec.seq.odometry[kf], rec.seq.times[kf]
        seg = W.odometry_segments(raw, t)
        truth = pose_at(rec.truth.times, rec.truth.poses, t)
        t0 = time.perf_counter()
        odo = Odometer(wp.scan_match)
        matched = odo.extend([rec.seq.scans[i] for i in kf], raw, seg)
        bounds = W.segment_bounds(raw, odo.segments, wp.d_s, wp.step)
        ms.append(dict(family=rec.meta["family"], ms=1000 * (time.perf_counter() - t0) / len(kf)))
        for name, o in (("input", raw), ("matched", matched)):
            e_xy, e_th = window_errors(bounds, o, truth)
            errs.append(pd.DataFrame(dict(family=rec.meta["family"], odometry=name, err_m=e_xy,
                                          err_deg=e_th)))  # fmt: skip
    e = pd.concat(errs, ignore_index=True)
    q90 = lambda x: x.quantile(0.9)  # noqa: E731
    tab = e.groupby(["family", "odometry"], sort=False).agg(
        windows=("err_m", "size"), median_m=("err_m", "median"), p90_m=("err_m", q90),
        median_deg=("err_deg", "median"), p90_deg=("err_deg", q90),
    ).reset_index()  # fmt: skip
    m = pd.DataFrame(ms).groupby("family", sort=False).agg(ms_per_keyframe=("ms", "median"))
    tab = tab.merge(m, on="family")
    OUT.mkdir(exist_ok=True)
    tab.to_csv(OUT / "bench_scanmatch.csv", index=False)
    print(tab.round(3).to_markdown(index=False))
    fams = list(dict.fromkeys(e["family"]))
    fig, axs = plt.subplots(1, len(fams), figsize=(2.6 * len(fams), 3), sharey=False)
    for ax, f in zip(np.atleast_1d(axs), fams, strict=True):
        g = e[e["family"] == f]
        data = [g[g["odometry"] == o]["err_deg"].to_numpy() for o in ("input", "matched")]
        ax.boxplot(data, showfliers=False)
        ax.set_xticks([1, 2], ["input", "matched"])
        ax.set_title(f, fontsize=9)
        ax.set_ylabel("window heading error (deg)" if f == fams[0] else "")
    fig.suptitle("6 m window heading error against the truth: input vs LiDAR odometry")
    fig.tight_layout()
    fig.savefig(OUT / "bench_scanmatch.png", dpi=110)
    print(f"wrote {OUT / 'bench_scanmatch.csv'} and {OUT / 'bench_scanmatch.png'}")
    return tab


if __name__ == "__main__":
    main()
