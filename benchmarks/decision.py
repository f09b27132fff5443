"""Decision-layer timing: every window x policy x threshold set of one run, and a full batch.

Compile time is reported apart; run times are medians of repeated calls, as wall time and as
process CPU time (all threads; steadier than wall time on a shared machine), with the 1-minute
load average next to them. Cases: ``one_run`` and ``batch`` (S=4 threshold sets, J=64) and
``study`` (the study's sweep: 120 runs, S=1, J=32). Writes ``results/bench_decision.csv``.
Usage: ``python benchmarks/decision.py [--runs 100] [--cases one_run,batch,study]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import platform
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from mfcl_jax import se2
from mfcl_jax.decision import DecisionParams, decision_maps, evaluate, policy_names, variants

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from tests.test_decision_scenes import PITCH, row_of_rooms, walk  # noqa: E402


def synth_batch(R, K, J, T, seed=0):
    """Random-ish runs in the 4-room row: true, +-pitch aliases and clutter candidates."""
    rng = np.random.default_rng(seed)
    tb = walk([[10, 2.5], [18, 2.5], [10, 2.5], [3, 2.5], [26, 2.5]], step=46.0 / (T - 1))[:T]
    H = np.zeros((R, K, J, 3), np.float32)
    S = rng.uniform(0, 0.5, (R, K, J)).astype(np.float32)
    trajs = np.zeros((R, T, 3), np.float32)
    ends = np.linspace(T // K, T - 1, K).astype(np.int32)
    for r in range(R):
        A = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-np.pi, np.pi)])
        trajs[r] = np.asarray(se2.compose(se2.inverse(A), tb))
        H[r] = A + np.concatenate([rng.normal(0, 5, (K, J, 2)), rng.normal(0, 0.5, (K, J, 1))], -1)
        H[r, :, 0] = A + rng.normal(0, 0.1, (K, 3)) * [1, 1, 0.02]
        H[r, :, 1] = A + [PITCH, 0, 0]
        S[r, :, 0] = rng.uniform(0.8, 1.0, K)
        S[r, :, 1] = rng.uniform(0.7, 1.05, K)
    return (
        H,
        S,
        np.ones((R, K, J), bool),
        trajs,
        np.ones((R, T), bool),
        np.tile(ends, (R, 1)),
        np.ones((R, K), bool),
    )


def bench(name, args, maps, params, var, reps, chunk):
    args = [jnp.asarray(a) for a in args]
    kw = {} if chunk is None else {"run_chunk": chunk}
    t0, c0 = time.perf_counter(), time.process_time()
    comp = evaluate.lower(*args, maps, params, var, **kw).compile()
    t_compile, c_compile = time.perf_counter() - t0, time.process_time() - c0
    times, cpu = [], []
    for _ in range(reps):
        t0, c0 = time.perf_counter(), time.process_time()
        jax.block_until_ready(comp(*args, maps, params, var))
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    R, K = args[0].shape[:2]
    S, V = params.tau_c.shape[0], len(policy_names())
    med = float(np.median(times))
    return dict(
        case=name,
        R=R,
        K=K,
        J=args[0].shape[2],
        T=args[3].shape[1],
        S=S,
        V=V,
        compile_s=t_compile,
        compile_cpu_s=c_compile,
        median_s=med,
        median_cpu_s=float(np.median(cpu)),
        per_decision_us=1e6 * med / (R * K * S * V),
        device=jax.devices()[0].device_kind,
        host=platform.node(),
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--windows", type=int, default=30)
    ap.add_argument("--J", type=int, default=64)
    ap.add_argument("--T", type=int, default=256)
    ap.add_argument("--sets", type=int, default=4)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--study-runs", type=int, default=120)
    ap.add_argument("--study-J", type=int, default=32)
    ap.add_argument("--cases", default="one_run,batch,study")
    ap.add_argument("--out", default="results/bench_decision.csv")
    a = ap.parse_args()
    maps = jax.tree.map(jnp.asarray, decision_maps(row_of_rooms()))
    params = DecisionParams.stack([DecisionParams(tau_c=t) for t in np.linspace(0.4, 0.7, a.sets)])
    var = variants()
    p1 = DecisionParams.stack([DecisionParams()])
    cases = {
        "one_run": lambda: bench(
            "one_run", synth_batch(1, a.windows, a.J, a.T), maps, params, var, a.reps, 1
        ),
        "batch": lambda: bench(
            "batch", synth_batch(a.runs, a.windows, a.J, a.T, 1), maps, params, var, a.reps, 8
        ),
        # the study's sweep: one threshold set, J=32, every policy
        "study": lambda: bench(
            "study",
            synth_batch(a.study_runs, a.windows, a.study_J, a.T, 2),
            maps,
            p1,
            var,
            a.reps,
            8,
        ),
    }
    rows = []
    for name in a.cases.split(","):
        rows.append(cases[name]())
        rows[-1]["load1"] = os.getloadavg()[0]
        print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    pathlib.Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(a.out, index=False)
    print(df.to_string(index=False))


if __name__ == "__main__":
    main()
