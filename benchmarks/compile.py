"""What the decision layer's compilation costs, and which part of the layer pays for it.

The study, the benchmark, the robot's first window and most of the test suite's time wait for
XLA to compile the decision layer (``decision.runs.scan_runs``: ``vmap`` over runs of
``lax.scan(layer.update)``). This script lowers (traces) and compiles that program for one
batch shape (4 runs x 16 windows x 32 candidates of the four-room row, ``benchmarks/
decision.py``'s synthetic runs) and several lane sets, each in a fresh subprocess with the
compilation cache off, so every figure is a cold compilation:

* ``study``: every policy and threshold lane of the study (``COUNT_VARIANTS``), the
  baselines and the rival search (the sweep's main program);
* ``no_baselines``, ``no_rival_search``: the same without the baselines' lanes / without the
  global search for rivals of a commit;
* ``ours``: the one lane a robot runs, with the rival search;
* ``ours_no_search``: that lane without the search;
* ``ours_unbatched``: ``ours_no_search`` for one run, ``lax.scan(update)`` without the
  ``vmap`` over runs (what batching adds).
* ``robot``: ``ours`` for one run without the ``vmap``: the program of a robot's step.

Medians of ``--repeats`` subprocesses per variant, the variants alternating. Writes
``results/bench_compile.csv`` and ``results/bench_compile.md`` (pasted into the
``<!-- BEGIN:bench_compile -->`` block of ``docs/speed.md``).

Usage: ``python benchmarks/compile.py [--repeats 3]`` (about 4 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"

VARIANTS = {  # name: (ours lanes, baselines, rival search, vmap over runs)
    "study": ("count", True, True, True),
    "no_baselines": ("count", False, True, True),
    "no_rival_search": ("count", True, False, True),
    "ours": ("ours", False, True, True),
    "ours_no_search": ("ours", False, False, True),
    "ours_unbatched": ("ours", False, False, False),
    "robot": ("ours", False, True, False),
}


def one(name: str) -> dict:
    """Lowers and compiles the variant's program in this process; returns its timings."""
    import time

    import jax

    from benchmarks.decision import synth_batch
    from mfcl_jax.decision import DecisionParams, layer, make_lanes, run_inputs
    from mfcl_jax.decision import runs as decision_runs
    from mfcl_jax.decision.lanes import COUNT_VARIANTS
    from mfcl_jax.sim.synthetic import row_of_rooms

    ours, baselines, search, batched = VARIANTS[name]
    fp = row_of_rooms()
    batch, cands = synth_batch(fp, 4, 16, 32, 128)
    lanes_ = COUNT_VARIANTS if ours == "count" else ("ours",)
    p, lanes, spec = make_lanes(DecisionParams(), lanes_, baselines, "ours" if search else None)
    got = {}

    def grab(args, caps, spec, n_img, rp):  # the arguments decide_runs compiles with
        got.update(args=args, statics=dict(caps=caps, spec=spec, n_img=n_img, rp=rp))
        raise StopIteration

    decision_runs._compile = grab
    try:
        decision_runs.decide_runs(run_inputs(batch, cands), batch.run_building, [fp], p, lanes,
                                  spec, runs_per_call=4)  # fmt: skip
    except StopIteration:
        pass
    args, st = got["args"], got["statics"]
    if batched:
        fn = jax.jit(decision_runs.scan_runs, static_argnames=tuple(st))
        call = (args, st)
    else:
        maps, fields, _, params, ln, ev = args

        def fn(maps, fields, params, ln, ev):
            m, f = (None if t is None else jax.tree.map(lambda a: a[0], t) for t in (maps, fields))
            state = layer.init(m, params, st["caps"], ln, st["spec"], f, st["n_img"], st["rp"])
            return jax.lax.scan(layer.update, state, ev)[1]

        fn = jax.jit(fn)
        call = ((maps, fields, params, ln, jax.tree.map(lambda a: a[0], ev)), {})
    t0 = time.perf_counter()
    lowered = fn.lower(*call[0], **call[1])
    t1 = time.perf_counter()
    lowered.compile()
    t2 = time.perf_counter()
    n_ops = lowered.as_text().count(" = stablehlo.")
    return dict(variant=name, lanes=len(spec.names), lower_s=t1 - t0, compile_s=t2 - t1,
                stablehlo_ops=n_ops)  # fmt: skip


def main(argv=None) -> int:
    import pandas as pd

    from mfcl_jax.study.readme import update_block

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--one", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one:
        print("RESULT " + json.dumps(one(a.one)))
        return 0
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "MFCL_CACHE_DIR": "off",
           "PYTHONPATH": str(ROOT)}  # fmt: skip
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    rows = []
    for rep in range(a.repeats):
        for name in VARIANTS:
            r = subprocess.run([sys.executable, __file__, "--one", name], cwd=ROOT, env=env,
                               capture_output=True, text=True, timeout=600)  # fmt: skip
            line = [ln for ln in r.stdout.splitlines() if ln.startswith("RESULT ")]
            if r.returncode or not line:
                print(r.stderr[-2000:], file=sys.stderr)
                return 1
            rows.append({**json.loads(line[0][7:]), "repeat": rep})
            print(f"{name:16s} lower {rows[-1]['lower_s']:5.1f} s  compile "
                  f"{rows[-1]['compile_s']:5.1f} s", flush=True)  # fmt: skip
    df = pd.DataFrame(rows)
    RESULTS.mkdir(exist_ok=True)
    df.to_csv(RESULTS / "bench_compile.csv", index=False)
    med = df.groupby("variant", sort=False).agg(
        lanes=("lanes", "first"), lower_s=("lower_s", "median"),
        compile_s=("compile_s", "median"), stablehlo_ops=("stablehlo_ops", "first"),
    ).reset_index()  # fmt: skip
    base = float(med.loc[med["variant"] == "study", "compile_s"].iloc[0])
    med["compile vs study"] = (med["compile_s"] / base).round(2)
    med["lower_s"], med["compile_s"] = med["lower_s"].round(1), med["compile_s"].round(1)
    head = (
        f"One run of `benchmarks/compile.py --repeats {a.repeats}`, "
        f"4 runs x 16 windows x 32 candidates, cold "
        f"(cache off), each variant in a fresh process, medians of {a.repeats}, the variants "
        f"alternating; load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} at the "
        f"end. lower = tracing and lowering (Python), compile = XLA; stablehlo_ops = "
        f"operations in the lowered program."
    )
    md = head + "\n\n" + med.to_markdown(index=False) + "\n"
    (RESULTS / "bench_compile.md").write_text(md)
    print("\n" + md)
    update_block(ROOT / "docs" / "speed.md", "bench_compile", RESULTS / "bench_compile.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
