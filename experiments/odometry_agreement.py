"""How far the LiDAR odometry's heading change between two windows strays from the input
odometry's and from the truth's: ``python -m experiments.odometry_agreement [out]``.

Per window step (``d_s = 6 m``, a 2 m step) of the four corrected CARMEN logs (their odometry
is derived from the corrected poses with drift), the raw Intel bag (real wheel odometry) and
two walks of four procedural buildings, it writes ``steps.csv`` (one row per step: the
absolute heading differences in degrees, LiDAR against input, LiDAR against truth, input
against truth) and ``summary.md`` (quantiles per source) to ``out`` (default
``results/odometry``). The question it answers: could a disagreement between the two
odometries flag a LiDAR-odometry fault (``docs/design.md``, LiDAR odometry)? Ground truth is
read here only to score.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

LOGS = ("intel", "freiburg-101", "orebro", "seattle")
FAMILIES = ("plain", "offices", "ring", "hall")
WINDOWS, LENGTH_M = 6, 30.0


def _recordings(cache: str):
    from mfcl_jax.sim import SimParams, families
    from mfcl_jax.sources import logs
    from mfcl_jax.sources.simulated import simulate

    recs = []
    for name in LOGS:
        recs += [("log", r) for r in logs.log_recordings(name, WINDOWS, LENGTH_M, cache_dir=cache)]
    recs += [("bag", r) for r in logs.bag_recordings(WINDOWS, LENGTH_M, cache_dir=cache)]
    for fam in FAMILIES:
        scene = families.make_scene(fam, 0)
        walks = list(scene.trajectories)[:2]
        recs += [("procedural", r) for r in simulate(scene, walks, [0], SimParams())]
    return recs


def steps(source: str, rec) -> pd.DataFrame:
    """One row per pair of consecutive windows of ``rec``."""
    from mfcl_jax import windows as W
    from mfcl_jax.se2 import wrap_host as wrap

    w = W.cut(rec.seq, W.WindowParams(d_s=6.0))
    truth = np.asarray(rec.truth.poses)[w.keyframes[w.bounds[:, 1]]]
    d_lidar = wrap(np.diff(w.X[:, 2]))
    d_input = wrap(np.diff(w.X_input[:, 2]))
    d_truth = wrap(np.diff(truth[:, 2]))
    deg = lambda a, b: np.rad2deg(np.abs(wrap(a - b)))  # noqa: E731
    return pd.DataFrame({
        "source": source,
        "run": rec.name,
        "to_window": np.arange(2, len(w) + 1),  # 1-based, as the benchmark's windows
        "lidar_vs_input_deg": deg(d_lidar, d_input),
        "lidar_vs_truth_deg": deg(d_lidar, d_truth),
        "input_vs_truth_deg": deg(d_input, d_truth),
    })  # fmt: skip


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0] if argv else "results/odometry")
    cache = str(Path("~/.cache/mfcl_jax/maps").expanduser())
    recs = _recordings(cache)
    table = pd.concat([steps(src, r) for src, r in recs], ignore_index=True)
    table["group"] = np.where(table.source == "log", table.run.str.split("/").str[0], table.source)
    cols = ["lidar_vs_input_deg", "lidar_vs_truth_deg", "input_vs_truth_deg"]
    q = table.groupby("group")[cols].quantile([0.5, 0.9, 0.99, 1.0]).round(2)
    q.index = q.index.set_names(["group", "quantile"])
    q = q.reset_index()
    q.insert(1, "steps", q.group.map(table.groupby("group").size()))
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "steps.csv", index=False)
    (out / "summary.md").write_text(q.to_markdown(index=False) + "\n")
    print(q.to_markdown(index=False))
    print(f"wrote {out}/steps.csv, {out}/summary.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
