"""Certification timing: what the per-window blocks cost (``decision.certify``).

The certification re-scores every window of a prefix under every explanation at its best fit
(``fitted.window_scores``, 13 poses per explanation) and also scores each window's
evidence again in ``CERT_BLOCKS`` contiguous blocks at the fitted pose. This script times, in
one run so the ratios are comparable:

* ``fit_blocks1``: the fitted scoring with one block (the whole window: the cost without
  sub-window evidence, up to one extra pass over the points);
* ``fit_blocksN``: the same with the default ``CERT_BLOCKS``;
* ``certify``: the whole ``certify.certify`` call (chain of scan-disjoint windows, fitted
  scoring, blocks, advantages) at one prefix.

Inputs: the four-room row walked to and fro (``sim.synthetic.row_walk``), the window
evidence it builds (128 points per window) and ``C`` competitors (shifts of the truth by up to
one room). Compile time is reported apart; run times are medians of repeated calls, as wall
time and as process CPU time, with the 1-minute load average. Writes
``results/bench_certify.csv`` and ``results/bench_certify.png``.
Usage: ``python benchmarks/certify.py [--competitors 30] [--reps 20]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import platform
import time

import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from mfcl_jax import se2  # noqa: E402
from mfcl_jax.decision import DecisionParams, certify, fitted  # noqa: E402
from mfcl_jax.sim.synthetic import HIDDEN_ANCHOR as A  # noqa: E402
from mfcl_jax.sim.synthetic import PITCH, row_walk  # noqa: E402
from mfcl_jax.sim.synthetic import ROW_K as K  # noqa: E402


def timed(fn, args, reps):
    """``(compile_s, compile_cpu_s, wall times, cpu times)`` of a jitted ``fn(*args)``."""
    t0, c0 = time.perf_counter(), time.process_time()
    comp = jax.jit(fn).lower(*args).compile()
    t_c, c_c = time.perf_counter() - t0, time.process_time() - c0
    wall, cpu = [], []
    for _ in range(reps):
        t0, c0 = time.perf_counter(), time.process_time()
        jax.block_until_ready(comp(*args))
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return t_c, c_c, np.asarray(wall), np.asarray(cpu)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--competitors", type=int, default=30)
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--out", default="results/bench_certify.csv")
    a = ap.parse_args()
    maps, run = row_walk()
    p = DecisionParams()
    X = jnp.asarray(run["X"])
    ev = [jnp.asarray(run[f]) for f in ("ev_points", "ev_origins", "ev_mask")]
    bounds = (jnp.asarray(run["window_start"]), jnp.asarray(run["window_end"]))
    rng = np.random.default_rng(0)
    n = a.competitors
    shifts = np.c_[rng.uniform(-PITCH, PITCH, (n, 2)), rng.uniform(-0.3, 0.3, n)]
    comp = jnp.asarray(np.asarray(se2.compose(shifts, A[None])), jnp.float32)
    t_star = jnp.asarray(A, jnp.float32)
    k = K - 1
    idx, ok = certify.chain(k, *bounds, jnp.any(ev[2], axis=1), 12)
    idx = np.asarray(idx)[np.asarray(ok)]
    anchors = jnp.concatenate([t_star[None], comp])
    poses = se2.compose(anchors[None], X[idx][:, None])  # (W, C + 1, 3)
    win = [e[idx] for e in ev]
    W, P = poses.shape[0], win[0].shape[1]

    def fit(n_blocks):
        def f(poses, pts, org, m):
            return fitted.window_scores(poses, pts, org, m, maps, p.cert_sigma, 1.0,
                                          fitted.FREE_PER_RAY, n_blocks=n_blocks)  # fmt: skip

        return f

    def whole(t_star, comp, X, pts, org, m):
        return certify.certify(k, t_star, comp, jnp.ones(comp.shape[0], bool), X, (pts, org, m),
                               bounds, maps, p)  # fmt: skip

    cases = {
        "fit_blocks1": (fit(1), (poses, *win)),
        f"fit_blocks{certify.CERT_BLOCKS}": (fit(certify.CERT_BLOCKS), (poses, *win)),
        "certify": (whole, (t_star, comp, X, *ev)),
    }
    rows, samples = [], {}
    for name, (fn, args) in cases.items():
        t_c, c_c, wall, cpu = timed(fn, args, a.reps)
        samples[name] = 1e3 * wall
        rows.append(
            dict(
                case=name,
                windows=W,
                explanations=a.competitors + 1,
                points=P,
                compile_s=t_c,
                compile_cpu_s=c_c,
                median_ms=float(1e3 * np.median(wall)),
                median_cpu_ms=float(1e3 * np.median(cpu)),
                reps=a.reps,
                device=jax.devices()[0].device_kind,
                host=platform.node(),
                load1=os.getloadavg()[0],
            )
        )
        print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    base = df.loc[df.case == "fit_blocks1", "median_ms"].iloc[0]
    df["ratio_to_blocks1"] = df.median_ms / base
    out = pathlib.Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    print(df.to_string(index=False))
    fig, ax = plt.subplots(figsize=(6, 3.2))
    ax.boxplot(list(samples.values()), tick_labels=list(samples))
    ax.set_ylabel("wall time per call (ms)")
    ax.set_title(f"certification, {W} windows x {a.competitors + 1} explanations x {P} points")
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"), dpi=110)
    print(f"wrote {out} and {out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
