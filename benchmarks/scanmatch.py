"""LiDAR odometry benchmark: accuracy inside windows and cost per keyframe.

Usage: python benchmarks/scanmatch.py [--seeds 0 1 2] [--drift 0.03] [--drift-yaw 2.0]
Writes results/bench_scanmatch.csv (one row per run x odometry) and
results/bench_scanmatch.png (window error distributions, input vs refined).

Data: the stand-in scenes' trajectories simulated with a wheel-like odometry drift
(``--drift`` of each increment's length, ``--drift-yaw`` deg per metre); every window's
relative pose error between its first and last keyframe (what bends a submap), for the input
odometry and the refined one. Timing: ``Odometer.extend`` over each run's keyframes, the
first call (compilation) reported apart; medians over runs of ms per keyframe.
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
from mfcl_jax.floorplan.scenes import get_scene  # noqa: E402
from mfcl_jax.scanmatch import Odometer, ScanMatchParams  # noqa: E402
from mfcl_jax.score import pose_at  # noqa: E402
from mfcl_jax.sim import SimParams  # noqa: E402
from mfcl_jax.sim.trajectory import TrajectoryParams  # noqa: E402
from mfcl_jax.sources.simulated import simulate  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "results"


def window_errors(bounds, odo, truth) -> tuple[np.ndarray, np.ndarray]:
    """Per window: translation (m) and heading (deg) error of first-to-last relative pose."""
    a, b = bounds[:, 0], bounds[:, 1]
    rel_t = se2.compose_host(se2.inverse_host(truth[a]), truth[b])
    rel_o = se2.compose_host(se2.inverse_host(odo[a]), odo[b])
    d = se2.compose_host(se2.inverse_host(rel_t), rel_o)
    return np.hypot(d[:, 0], d[:, 1]), np.degrees(np.abs(d[:, 2]))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--drift", type=float, default=0.03)
    ap.add_argument("--drift-yaw", type=float, default=2.0)
    a = ap.parse_args(argv)
    sim = SimParams(trajectory=TrajectoryParams(drift_xy=a.drift, drift_yaw_deg_per_m=a.drift_yaw))
    wp = W.WindowParams()
    Odometer().extend([np.zeros((4, 2))] * 2, np.zeros((2, 3)), np.zeros(2, int))  # warm-up
    rows, errs = [], {"input": [], "refined": []}
    for scene in ("three_rooms", "symmetric"):
        for rec in simulate(get_scene(scene), seeds=a.seeds, params=sim):
            kf = W.keyframes(rec.seq.odometry)
            raw = rec.seq.odometry[kf]
            seg = W.odometry_segments(raw, rec.seq.times[kf])
            bounds = W.segment_bounds(raw, rec.seq.times[kf], wp.d_s, wp.step)
            truth = pose_at(rec.truth.times, rec.truth.poses, rec.seq.times[kf])
            t0 = time.perf_counter()
            odo = Odometer(ScanMatchParams())
            ref = odo.extend([rec.seq.scans[i] for i in kf], raw, seg)
            dt = time.perf_counter() - t0
            for name, o in (("input", raw), ("refined", ref)):
                e_xy, e_th = window_errors(bounds, o, truth)
                errs[name].append((e_xy, e_th))
                rows.append(
                    dict(
                        scene=scene,
                        run=rec.name,
                        odometry=name,
                        keyframes=len(kf),
                        windows=len(bounds),
                        median_err_m=float(np.median(e_xy)),
                        p90_err_m=float(np.quantile(e_xy, 0.9)),
                        median_err_deg=float(np.median(e_th)),
                        p90_err_deg=float(np.quantile(e_th, 0.9)),
                        trusted=float(odo.trusted.mean()) if name == "refined" else np.nan,
                        ms_per_keyframe=1000 * dt / len(kf) if name == "refined" else np.nan,
                    )
                )
    df = pd.DataFrame(rows)
    OUT.mkdir(exist_ok=True)
    df.to_csv(OUT / "bench_scanmatch.csv", index=False)
    summ = df.groupby("odometry")[
        ["median_err_m", "p90_err_m", "median_err_deg", "p90_err_deg", "trusted", "ms_per_keyframe"]
    ].median()
    print(summ.round(3).to_string())
    fig, axs = plt.subplots(1, 2, figsize=(9, 3.5))
    for name, c in (("input", "tab:red"), ("refined", "tab:blue")):
        xy = np.concatenate([e[0] for e in errs[name]])
        th = np.concatenate([e[1] for e in errs[name]])
        axs[0].hist(xy, bins=40, alpha=0.6, color=c, label=name)
        axs[1].hist(th, bins=40, alpha=0.6, color=c, label=name)
    axs[0].set_xlabel("window first-to-last translation error (m)")
    axs[1].set_xlabel("window first-to-last heading error (deg)")
    axs[0].legend()
    fig.suptitle(f"LiDAR odometry vs input (drift {a.drift:g}, {a.drift_yaw:g} deg/m)")
    fig.tight_layout()
    fig.savefig(OUT / "bench_scanmatch.png", dpi=120)
    print(f"wrote {OUT / 'bench_scanmatch.csv'} and {OUT / 'bench_scanmatch.png'}")


if __name__ == "__main__":
    main()
