"""Where the test suite's time goes: compiling, and which programs.

Runs the suite as the README runs it (``python -m pytest``, two xdist workers, a fresh
compilation cache for the session: ``tests/conftest.py``) with the plugin
``benchmarks/_suite_listener.py``, which attributes JAX's tracing, lowering and XLA
compilation to the test running at the time. Prints and writes:

* per test file: wall seconds (setup, call and teardown summed over its tests), XLA's compile
  seconds, tracing and lowering seconds, programs compiled;
* per program name (``jit(scan_runs)``: the decision layer's batch; ``jit(<lambda>)``: the
  robot's step and the front-end's call; ``jit(add)`` and the like: single operations run
  outside ``jit``, each shape compiled on its own): compilations and seconds;
* the eager operations together: compilations under 0.2 s whose name is one ``jax.numpy``
  operation.

Compile seconds are the workers' own: what an ``mfcl`` or ``experiments`` subprocess compiles
counts in its test's wall time only. Seconds are per worker and add up over both workers, so
the total exceeds the run's wall clock.

Writes ``results/bench_suite.csv`` (per file), ``results/bench_suite_programs.csv``,
``results/bench_suite.md`` (pasted into the ``<!-- BEGIN:bench_suite -->`` block of
``docs/speed.md``) and ``results/bench_suite.png``.

Usage: ``python benchmarks/suite.py [pytest args]`` (one run of the suite: 6-7 minutes on
2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
EAGER_S = 0.2  # a compilation shorter than this, of a one-operation program, is eager dispatch


def _frames(folder: pathlib.Path):
    import pandas as pd

    files = sorted(folder.glob("gw*.json")) or sorted(folder.glob("main.json"))
    if not files:
        raise SystemExit(f"suite: the plugin wrote nothing into {folder}; did pytest start?")
    tests, progs = [], []
    for f in files:
        d = json.loads(f.read_text())
        for t, c in d["tests"].items():
            tests.append({"worker": d["worker"], "test": t, **c})
        progs += [{"worker": d["worker"], **p} for p in d["programs"]]
    tests, progs = pd.DataFrame(tests).fillna(0.0), pd.DataFrame(progs)
    tests["file"] = tests["test"].str.split("::").str[0].str.replace("tests/", "", regex=False)
    progs["file"] = progs["test"].str.split("::").str[0].str.replace("tests/", "", regex=False)
    return tests, progs


def _eager(progs):
    """Rows of the eager single operations: programs named after one operation whose
    compilations took under ``EAGER_S`` each on average (over every test that compiled them)."""
    one_op = progs["program"].str.fullmatch(r"jit\(\w+\)")  # not jit(<lambda>)
    per = progs.groupby("program")[["seconds", "n"]].transform("sum")
    return one_op & (per["seconds"] / per["n"].clip(lower=1) < EAGER_S)


def report(tests, progs, wall_s: float):
    for c in ("wall_s", "compile_s", "trace_s", "lower_s", "compile_n"):
        if c not in tests:
            tests[c] = 0.0
    per_file = (
        tests.groupby("file")[["wall_s", "compile_s", "trace_s", "lower_s", "compile_n"]]
        .sum()
        .sort_values("wall_s", ascending=False)
    )
    per_file["compile_n"] = per_file["compile_n"].astype(int)
    eager = _eager(progs)
    per_prog = (
        progs.groupby("program")[["n", "seconds"]].sum().sort_values("seconds", ascending=False)
    )
    per_prog["n"] = per_prog["n"].astype(int)
    top_files = (
        progs.groupby(["program", "file"])["seconds"].sum().reset_index()
        .sort_values("seconds", ascending=False).groupby("program")
        .apply(lambda g: ", ".join(f"{f} {s:.0f}" for f, s in zip(g.file[:3], g.seconds[:3],
                                                                  strict=False)),
               include_groups=False)
    )  # fmt: skip
    per_prog["most_in"] = top_files.reindex(per_prog.index)
    total = per_file.sum(numeric_only=True)
    comp = total["compile_s"] + total["trace_s"] + total["lower_s"]
    workers = tests.groupby("worker")["wall_s"].sum()
    balance = ", ".join(f"{w} {v:.0f} s" for w, v in workers.items())
    head = (
        f"One run of `benchmarks/suite.py`: `python -m pytest` (two workers, a fresh "
        f"compilation cache), {wall_s:.0f} s of wall time; the tests' seconds summed over both "
        f"workers: {total['wall_s']:.0f} s ({balance}), of which in-process compilation "
        f"{comp:.0f} s ({100 * comp / max(total['wall_s'], 1e-9):.0f} %: XLA "
        f"{total['compile_s']:.0f} s, tracing {total['trace_s']:.0f} s, lowering "
        f"{total['lower_s']:.0f} s; subprocesses' compilations not counted); eager operations "
        f"(one-operation programs under {EAGER_S} s each) {int(progs.loc[eager, 'n'].sum())} "
        f"compilations, {progs.loc[eager, 'seconds'].sum():.0f} s of XLA."
    )
    md = [head, "", "Test files, heaviest first (seconds summed over their tests):", ""]
    md.append(per_file.head(15).round(1).to_markdown())
    md += ["", "Programs, by XLA compile seconds (all files):", ""]
    md.append(per_prog[~per_prog.index.isin(progs.loc[eager, "program"])].head(10).round(1)
              .to_markdown())  # fmt: skip
    return per_file, per_prog, "\n".join(md) + "\n"


def figure(per_file, path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    top = per_file.head(20).iloc[::-1]
    fig, ax = plt.subplots(figsize=(8, 6))
    comp = top["compile_s"]
    tl = top["trace_s"] + top["lower_s"]
    rest = (top["wall_s"] - comp - tl).clip(lower=0)
    ax.barh(top.index, comp, label="XLA compile")
    ax.barh(top.index, tl, left=comp, label="tracing + lowering")
    ax.barh(top.index, rest, left=comp + tl, label="the rest (running, subprocesses)")
    ax.set_xlabel("seconds (summed over the file's tests)")
    ax.set_title("Where the test suite's time goes, per file")
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    from mfcl_jax.study.readme import update_block

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("pytest_args", nargs="*", help="extra arguments for pytest")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        env = {
            **os.environ,
            "MFCL_SUITE_OUT": tmp,
            "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        }
        cmd = [sys.executable, "-m", "pytest", "-p", "benchmarks._suite_listener",
               "-p", "no:cacheprovider", *args.pytest_args]  # fmt: skip
        print("running:", " ".join(cmd), flush=True)
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=ROOT, env=env)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            print(f"suite: pytest exited {r.returncode}; timings below cover what ran",
                  file=sys.stderr)  # fmt: skip
        tests, progs = _frames(pathlib.Path(tmp))
    per_file, per_prog, md = report(tests, progs, wall)
    RESULTS.mkdir(exist_ok=True)
    per_file.to_csv(RESULTS / "bench_suite.csv")
    per_prog.to_csv(RESULTS / "bench_suite_programs.csv")
    (RESULTS / "bench_suite.md").write_text(md)
    figure(per_file, RESULTS / "bench_suite.png")
    update_block(ROOT / "docs" / "speed.md", "bench_suite", RESULTS / "bench_suite.md")
    print(md)
    return r.returncode


if __name__ == "__main__":
    raise SystemExit(main())
