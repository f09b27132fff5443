"""Old code against new code, timed in ONE run so that the ratios are comparable.

The OLD code is a git ref (default ``fa55350``), checked out into a temporary worktree
(``git worktree add --detach``, removed at the end, also on error); the NEW code is this
working tree. Each side runs as a subprocess of the same venv Python, with ``cwd`` and
``PYTHONPATH`` set to its own tree (``PYTHONPATH`` comes before the venv's editable install;
each side's ``mfcl_jax.__file__`` is checked first). ``mfcl`` is called as
``python -c "from mfcl_jax.cli import main; ..."`` so that the tree's module runs, not the
installed console script. Every subprocess runs under ``/usr/bin/time -v`` (peak resident
memory of the child) with ``PYTHONUNBUFFERED=1`` (the old CLI does not flush its status lines;
without it a pipe would hold them to the end of the run).

Cases (wall time from process start to exit; "cold": a fresh, empty ``mfcl`` compilation
cache folder, ``MFCL_CACHE_DIR``; "warm": the same folder again):

``sweep``
    ``python -m experiments.sweep d_s=5,6,7 out=TMP figures=true progress=false``, once per
    side (the sweep turns no persistent cache on: every run is cold, as in a fresh clone).
    The tables the two sides write (every ``.csv`` and ``.csv.gz`` but the stage timings,
    content compared) are reported as identical or by the names of the files that differ.
``office``
    ``mfcl localize OFFICE --out TMP.jsonl`` on a dataset simulated once (new code, one
    odometry pose per scan, which both sides read) in the Office_A IFC plan along the README's
    11-waypoint walk: cold, then ``--repeats`` warm runs. Also the time to the first status
    line (``k=...``) on stdout.
``many``
    ``mfcl localize FOLDER --out-dir TMP --quiet`` on 20 simulated datasets
    (``benchmarks/cli_many.make_datasets`` of the new tree, written once; 18-37 windows each):
    cold, then ``--repeats`` warm runs. Its peak resident memory is the issue's second target.

Writes ``results/bench_versions.csv`` (one row per run, rewritten after every run, so an
interrupted run keeps what it measured), ``results/bench_versions.md`` (medians, ratio old/new,
peak resident memory) and ``results/bench_versions.png``, and pastes the ``.md`` into the
``<!-- BEGIN:bench_versions -->`` block of ``docs/speed.md`` (``mfcl_jax.study.readme``; only
that block). The machine's load average at start and end and any other heavy jobs
(``pgrep``) are recorded in the header. A case that fails is logged and named in the header;
the other cases still run.

Usage: ``python benchmarks/versions.py [--cases sweep,office,many] [--repeats 3] [--old REF]
[--datasets 20] [--stop-at HH:MM]`` (all cases: about 35-45 minutes on 2 shared cores; a quick
check: ``--cases office --repeats 1``).
"""

from __future__ import annotations

import argparse
import datetime
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from benchmarks._versions_cases import Bench, TimeUp  # noqa: E402
from benchmarks._versions_report import paste_into_docs, summarize, write_outputs  # noqa: E402
from benchmarks._versions_sides import (  # noqa: E402
    ROOT,
    SIDES,
    check_import,
    load,
    log,
    other_jobs,
)

RESULTS = ROOT / "results"


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="sweep,office,many", help="comma list (sweep,office,many)")
    ap.add_argument("--repeats", type=int, default=3, help="warm repeats (3)")
    ap.add_argument("--old", default="fa55350", help="git ref of the old code (fa55350)")
    ap.add_argument("--out", default=str(RESULTS / "bench_versions.csv"))
    ap.add_argument("--docs", default=str(ROOT / "docs" / "speed.md"),
                    help="page whose bench_versions block gets the table ('' : none)")  # fmt: skip
    ap.add_argument("--datasets", type=int, default=20, help="many: datasets (20)")
    ap.add_argument("--stop-at", metavar="HH:MM",
                    help="local time after which no run starts; the tables are written from "
                    "the runs made (Ctrl-C or SIGTERM do the same at once)")  # fmt: skip
    a = ap.parse_args(argv)
    stop_at = None
    if a.stop_at:
        stop_at = datetime.datetime.combine(
            datetime.date.today(), datetime.time.fromisoformat(a.stop_at)
        )
    cases = [c.strip() for c in a.cases.split(",") if c.strip()]
    bad = set(cases) - {"sweep", "office", "many"}
    if bad:
        ap.error(f"unknown cases: {', '.join(sorted(bad))}")
    csv_path = pathlib.Path(a.out).resolve()
    signal.signal(signal.SIGINT, signal.default_int_handler)  # also when started in background
    signal.signal(signal.SIGTERM, _interrupt)  # ``kill PID``: stop as Ctrl-C does

    load0, jobs0 = load(), other_jobs()
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    old_sha = subprocess.run(["git", "rev-parse", "--short", a.old], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    code_dirs = ["mfcl_jax", "experiments", "conf"]
    dirty = subprocess.run(["git", "status", "--porcelain", "--", *code_dirs],
                           cwd=ROOT, capture_output=True, text=True).stdout.strip()  # fmt: skip
    log(f"old {a.old} ({old_sha}) vs new working tree (HEAD {head}{', modified' if dirty else ''})")
    log(f"cases {cases}, {a.repeats} warm repeats; load {load0}; other jobs: {len(jobs0)}")
    for j in jobs0:
        log(f"  running: {j[:150]}")

    failed, cut = [], ""
    with tempfile.TemporaryDirectory(prefix="bench_versions_") as tmp:
        tmp = pathlib.Path(tmp)
        old_tree = tmp / "old"
        subprocess.run(["git", "worktree", "add", "--detach", str(old_tree), a.old], cwd=ROOT,
                       check=True, capture_output=True)  # fmt: skip
        try:
            trees = {"old": old_tree, "new": ROOT}
            for side in SIDES:
                check_import(side, trees[side])
            bench = Bench(trees, tmp, a.repeats, csv_path, stop_at, a.datasets)
            for case in cases:
                t0 = time.perf_counter()
                try:
                    getattr(bench, case)()
                except (RuntimeError, OSError, subprocess.CalledProcessError) as e:
                    failed.append(case)
                    log(f"{case}: FAILED: {e}")
                except (TimeUp, KeyboardInterrupt) as e:
                    cut = f"stopped early in {case} ({str(e) or 'interrupted'})"
                    log(cut)
                    break
                log(f"{case}: done in {time.perf_counter() - t0:.0f} s")
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(old_tree)], cwd=ROOT,
                           capture_output=True)  # fmt: skip
            subprocess.run(["git", "worktree", "prune"], cwd=ROOT, capture_output=True)
            log("old worktree removed")

    load1, jobs1 = load(), other_jobs()
    busy = "other jobs running" if (jobs0 or jobs1) else "no other jobs running"
    header = (
        f"Old code ({a.old}, {old_sha}) vs new code (HEAD {head}"
        f"{', working tree modified' if dirty else ''}), one run of `benchmarks/versions.py "
        f"--cases {','.join(cases)} --repeats {a.repeats}"
        f"{'' if a.datasets == 20 else f' --datasets {a.datasets}'}`; medians "
        f"of the runs (cold: 1, warm: {a.repeats}); {os.cpu_count()} cores; load average "
        f"(1/5/15 min) {load0} at start, {load1} at end; {busy} ({len(jobs0)} at start, "
        f"{len(jobs1)} at end). Wall time from process start to exit; cold = fresh empty "
        f"compilation cache, warm = the same cache again; peak RSS = the largest over the runs "
        f"(old / new), from /usr/bin/time -v."
        + (f" FAILED (see the log): {', '.join(failed)}." if failed else "")
        + (f" {cut[0].upper()}{cut[1:]}: cases after it not run." if cut else "")
    )
    summary = summarize(bench.rows, bench.notes)
    md_path = write_outputs(bench.rows, summary, header, csv_path)
    log(f"wrote {csv_path} and its .md / .png")
    if a.docs and summary:
        ok = paste_into_docs(md_path, pathlib.Path(a.docs))
        log(f"{a.docs}: bench_versions block {'refreshed' if ok else 'NOT FOUND'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
