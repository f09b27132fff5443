"""Decision-layer timing: every window x lane (policy x threshold set) of one run, and a batch.

The batch decision is ``decision.runs``: ``run_inputs`` lays the windows out on the host,
``decide_runs`` decides every lane at every window in one compiled call per chunk of runs
(``vmap`` over runs of ``lax.scan(layer.update)``), the rival search included, as the study
and the benchmark call it. The first call compiles: its ``compile_s`` is ``decide_runs``'
compile time and ``compile_cpu_s`` the process CPU time of that call less a later call's.
Run times are medians of ``--reps`` further calls: ``median_s`` the compiled calls alone
(``decide_runs``' ``run_s``, what ``per_decision_us`` divides), ``median_call_s`` and
``median_cpu_s`` the whole ``decide_runs`` call (maps, padding, transfers) as wall time and
process CPU time (all threads; steadier than wall time on a shared machine), with the
1-minute load average next to them. ``V`` is the lanes per threshold set (every variant of
``COUNT_VARIANTS`` and the baselines). Cases: ``one_run`` and ``batch`` (S=4 threshold sets,
J=64) and ``study`` (the study's sweep: 120 runs, S=1, J=32). Writes
``results/bench_decision.csv``.
Usage: ``python benchmarks/decision.py [--runs 100] [--cases one_run,batch,study]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import platform
import time

import jax
import numpy as np
import pandas as pd

from mfcl_jax import se2
from mfcl_jax import windows as W
from mfcl_jax.bench.run import DEFAULT_SET, KNOB_SETS
from mfcl_jax.decision import DecisionParams, make_lanes, run_inputs
from mfcl_jax.decision import runs as decision_runs
from mfcl_jax.decision.lanes import COUNT_VARIANTS
from mfcl_jax.frontend.candidates import Candidates
from mfcl_jax.sim.synthetic import PITCH, evidence_at, row_of_rooms, walk  # noqa: E402


def synth_batch(fp, R, K, J, T, seed=0):
    """Random-ish runs in the 4-room row: true, +-pitch aliases and clutter candidates.

    Returns the ``WindowBatch`` (one odometry segment per run, disjoint windows, each
    window's evidence a ray cast of the walls at its true pose) and its ``Candidates``."""
    rng = np.random.default_rng(seed)
    tb = walk([[10, 2.5], [18, 2.5], [10, 2.5], [3, 2.5], [26, 2.5]], step=46.0 / (T - 1))[:T]
    T = len(tb)
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
    X = trajs[:, ends]  # (R, K, 3) odometry pose of each window's last keyframe
    Y = np.asarray(se2.compose(H, X[:, :, None]), np.float32)  # candidates ^B T_S
    ev = [np.tile(e, (R,) + (1,) * e.ndim) for e in evidence_at(fp, tb[ends])]
    n = R * K
    runs = W.RunBatch(
        traj=trajs,
        traj_seg=np.zeros((R, T), np.int32),
        traj_mask=np.ones((R, T), bool),
        window_start=np.tile(np.r_[0, ends[:-1] + 1].astype(np.int32), (R, 1)),
        window_end=np.tile(ends, (R, 1)),
        window_mask=np.ones((R, K), bool),
        submap=np.arange(n, dtype=np.int32).reshape(R, K),
    )
    subs = W.SubmapBatch(
        points=np.zeros((n, 1, 2), np.float32),  # not read by the decision
        origins=np.zeros((n, 1, 2), np.float32),
        mask=np.zeros((n, 1), bool),
        X=X.reshape(n, 3),
        run=np.repeat(np.arange(R, dtype=np.int32), K),
        window=np.tile(np.arange(K, dtype=np.int32), R),
        t=np.zeros(n),
        n_dropped=np.zeros(n, np.int32),
    )
    p, o, m = (e.reshape(n, *e.shape[2:]) for e in ev)
    evidence = W.Evidence(p, o, m, p, m)  # the scan at the window's end is its last metre
    batch = W.WindowBatch(subs, runs, np.zeros(n, np.int32), np.zeros(R, np.int32), evidence)
    cands = Candidates(
        Y.reshape(n, J, 3), S.reshape(n, J), np.ones((n, J), bool), np.zeros(n, np.int32)
    )
    return batch, cands


def bench(name, fp, batch, cands, sets, reps, chunk):
    """Compile, then ``reps`` timed calls of ``decide_runs`` on ``batch``."""
    primary_set = DEFAULT_SET if len(sets) > DEFAULT_SET else 0
    p, lanes, spec = make_lanes(sets, COUNT_VARIANTS, True, "ours", primary_set)
    inputs = run_inputs(batch, cands)

    def call():
        t0, c0 = time.perf_counter(), time.process_time()
        _, tm = decision_runs.decide_runs(inputs, batch.run_building, [fp], p, lanes, spec,
                                          runs_per_call=chunk)  # fmt: skip
        return tm, time.perf_counter() - t0, time.process_time() - c0

    decision_runs._COMPILED.clear()  # every case reports its own compilation
    first, _, c_first = call()
    tms, wall, cpu = [], [], []
    for _ in range(reps):
        tm, w, c = call()
        tms.append(tm)
        wall.append(w)
        cpu.append(c)
    R, K = batch.runs.n_runs, batch.runs.n_windows
    S, V = spec.n_sets, len(spec.names) // spec.n_sets
    med = float(np.median([tm["run_s"] for tm in tms]))
    med_cpu = float(np.median(cpu))
    return dict(
        case=name,
        R=R,
        K=K,
        J=int(cands.pose.shape[1]),
        T=int(batch.runs.traj.shape[1]),
        S=S,
        V=V,
        runs_per_call=min(chunk, R),  # decide_runs never pads past the batch
        compile_s=first["compile_s"],
        compile_cpu_s=max(c_first - med_cpu, 0.0),
        median_s=med,
        median_call_s=float(np.median(wall)),
        median_cpu_s=med_cpu,
        per_decision_us=1e6 * med / (R * K * S * V),
        searches=tms[-1]["searches"],
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
    if not 1 <= a.sets <= len(KNOB_SETS):
        ap.error(f"--sets must be 1..{len(KNOB_SETS)} (bench.run.KNOB_SETS)")
    fp = row_of_rooms()
    # threshold sets differ only in the knobs (``decision.KNOBS``): the benchmark's sweep
    sets = [DecisionParams().replace(**k) for k in KNOB_SETS[: a.sets]]
    one = [DecisionParams()]
    cases = {
        "one_run": lambda: bench(
            "one_run", fp, *synth_batch(fp, 1, a.windows, a.J, a.T), sets, a.reps, 1
        ),
        "batch": lambda: bench(
            "batch", fp, *synth_batch(fp, a.runs, a.windows, a.J, a.T, 1), sets, a.reps, 8
        ),
        # the study's sweep: one threshold set, J=32, every policy
        "study": lambda: bench(
            "study",
            fp,
            *synth_batch(fp, a.study_runs, a.windows, a.study_J, a.T, 2),
            one,
            a.reps,
            8,
        ),  # fmt: skip
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
