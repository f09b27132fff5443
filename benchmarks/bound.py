"""How long the branch and bound over every placement (``experiments.audit.path_certify``) takes:
``python benchmarks/bound.py [--repeats N]`` (about 5 minutes).

For the first walk of three procedural buildings, the path of windows 1..k (k = 3, 6, 9) is
placed at its true anchor, polished, and searched for a competitor within ``log(100)`` (the
``ours_unique_a2`` margin). Prints and saves (``DIR/bound.md``, default ``results/speed``) the
first call (compilation included) and the median of ``N`` warm calls, apart, with the outcome
and the cells bounded. Ground truth gives ``A*`` here only to have a realistic test to time.
Writes ``results/bench_bound.csv``, ``results/bench_bound.md`` (pasted into the
``<!-- BEGIN:bench_bound -->`` block of ``docs/speed.md``) and ``results/bench_bound.png``.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np
import pandas as pd

from experiments.audit import path_bound, path_certify
from mfcl_jax import se2
from mfcl_jax import windows as W
from mfcl_jax.decision import rivals
from mfcl_jax.frontend import path_llr
from mfcl_jax.sim import SimParams, families
from mfcl_jax.sources.simulated import simulate
from mfcl_jax.windows.arrays import evidence_sample

FAMILIES = ("plain", "ring", "offices")
PREFIXES = (3, 6, 9)


def case(rec, w, k: int, fields):
    """``(pe, A*, L*, x_now)`` of windows 1..k of ``rec``."""
    ev = [evidence_sample(w.points[i], w.origins[i]) for i in range(k)]
    X = np.asarray(w.X[:k], np.float32)
    b = np.asarray(w.bounds)
    odo = np.asarray(w.odometry)[b[0, 0] : b[k - 1, 1] + 1]
    length = float(np.sum(np.hypot(*np.diff(odo[:, :2], axis=0).T)))
    pe = path_llr.path_evidence(np.stack([e[0] for e in ev]), np.stack([e[1] for e in ev]),
                                np.stack([e[2] for e in ev]), X, length)  # fmt: skip
    truth = np.asarray(rec.truth.poses)[w.keyframes[b[k - 1, 1]]]
    a0 = se2.compose_host(truth, se2.inverse_host(np.asarray(X[-1], np.float64)))
    a, L = path_llr.refine(jnp.asarray(a0, jnp.float32), pe, fields)
    return pe, np.asarray(a, np.float64), float(L), X[-1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    rows = []
    for fam in FAMILIES:
        scene = families.make_scene(fam, 0)
        rec = simulate(scene, [list(scene.trajectories)[0]], [0], SimParams())[0]
        w = W.cut(rec.seq, W.WindowParams(d_s=6.0))
        fields = jax.tree.map(jnp.asarray, rivals.rival_fields(scene.floorplan))
        bf = path_bound.bound_fields(fields)
        for k in PREFIXES:
            if k > len(w):
                continue
            pe, a, L, x_now = case(rec, w, k, fields)
            tau = L - math.log(100.0)
            t0 = time.perf_counter()
            r = path_certify.certify(pe, fields, bf, a, x_now, tau)
            first = time.perf_counter() - t0
            warm = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                path_certify.certify(pe, fields, bf, a, x_now, tau)
                warm.append(time.perf_counter() - t0)
            rows.append(dict(building=fam, grid="x".join(map(str, bf.capped.shape)), windows=k,
                             metres=round(float(pe.length), 1), outcome=r.outcome,
                             cells=r.cells, first_s=round(first, 2),
                             warm_median_s=round(float(np.median(warm)), 2)))  # fmt: skip
            print(rows[-1], flush=True)
    table = pd.DataFrame(rows)
    head = (f"One run of `benchmarks/bound.py --repeats {args.repeats}`, "
            f"first call (compilation included) and the "
            f"median of {args.repeats} warm calls; load average "
            f"{' '.join(f'{x:.2f}' for x in os.getloadavg())} at the end.")  # fmt: skip
    out = Path("results")
    table.to_csv(out / "bench_bound.csv", index=False)
    (out / "bench_bound.md").write_text(head + "\n\n" + table.to_markdown(index=False) + "\n")
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for fam, g in table.groupby("building", sort=False):
        ax.plot(g.metres, g.warm_median_s, "o-", label=fam)
    ax.set_xlabel("metres of path")
    ax.set_ylabel("seconds per test (warm median)")
    ax.set_title("branch and bound over every placement, alpha = 1e-2")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "bench_bound.png", dpi=120)
    print(head)
    print(table.to_markdown(index=False))
    from mfcl_jax.study.readme import update_docs

    print("refreshed:", update_docs("results"))


if __name__ == "__main__":
    main()
