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
import gzip
import os
import pathlib
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
OFFICE_IFC = ROOT.parent / "shared" / "data" / "ifc" / "Office_A_20110811.ifc"
WAYPOINTS = (
    "x,y\n6,-27\n6.9,-15.1\n6.9,-13.5\n25.2,-13.5\n25.2,-15.1\n25.4,-29.3\n25.4,-30.9\n"
    "20.3,-30.8\n27.7,-30.8\n27.7,-29.2\n33.8,-29.4\n"
)
MFCL = "import sys; from mfcl_jax.cli import main; sys.exit(main())"
OTHER_JOBS = "experiments.benchmark|experiments.real|pytest|experiments.sweep"
SIDES = ("old", "new")
TIME = "/usr/bin/time"  # GNU time: -v reports the peak resident set size


def log(msg: str) -> None:
    stamp = datetime.datetime.now().strftime("%H:%M:%S")
    print(f"[{stamp}] {msg}", flush=True)


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def other_jobs() -> list[str]:
    """Command lines of other heavy jobs on the machine (not this script's children)."""
    r = subprocess.run(["pgrep", "-af", OTHER_JOBS], capture_output=True, text=True)
    mine = {str(os.getpid())}
    return [ln for ln in r.stdout.splitlines() if ln and ln.split()[0] not in mine]


def side_env(tree: pathlib.Path, cache: pathlib.Path | None) -> dict:
    """The side's environment: its tree first on ``PYTHONPATH``; ``MFCL_CACHE_DIR`` (the
    ``mfcl`` command's persistent compilation cache) set to ``cache``. JAX's own
    ``JAX_COMPILATION_CACHE_DIR`` is removed, so the sweep (which turns no cache on) runs as
    it does for a user."""
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONUNBUFFERED": "1"}
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    if cache is not None:
        env["MFCL_CACHE_DIR"] = str(cache)
    return env


def check_import(side: str, tree: pathlib.Path) -> str:
    """``mfcl_jax.__file__`` as the side's subprocess sees it; it must lie in ``tree``."""
    r = subprocess.run(
        [sys.executable, "-c", "import mfcl_jax; print(mfcl_jax.__file__)"],
        cwd=tree, env=side_env(tree, None), capture_output=True, text=True, check=True,
    )  # fmt: skip
    path = r.stdout.strip()
    ok = pathlib.Path(path).resolve().is_relative_to(tree.resolve())
    log(f"{side}: mfcl_jax from {path}" + ("" if ok else "  <-- NOT ITS OWN TREE"))
    if not ok:
        raise RuntimeError(f"{side} imports {path}, not its tree {tree}")
    return path


def timed(cmd, cwd, env, logfile: pathlib.Path, first_line: bool = False) -> dict:
    """Runs ``cmd`` under ``/usr/bin/time -v``; wall time, time to the first status line
    (``k=...`` on stdout, when ``first_line``) and the child's peak resident memory."""
    rusage = logfile.with_suffix(".time")
    full = [TIME, "-v", "-o", str(rusage), *cmd]
    first = None
    with open(logfile, "w") as out, open(logfile.with_suffix(".err"), "w") as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(full, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=err,
                             text=True, start_new_session=True)  # fmt: skip
        try:
            for line in p.stdout:
                if first is None and first_line and line.startswith("k="):  # a status line
                    first = time.perf_counter() - t0
                out.write(line)
            rc = p.wait()
        except BaseException:  # Ctrl-C: GNU time does not pass it on; end the whole group
            os.killpg(p.pid, signal.SIGTERM)
            p.wait()
            raise
        wall = time.perf_counter() - t0
    if rc != 0:
        tail = logfile.with_suffix(".err").read_text()[-3000:]
        raise RuntimeError(f"exit {rc}: {' '.join(map(str, cmd))}\n{tail}")
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", rusage.read_text())
    rss = int(m.group(1)) / 1024 if m else float("nan")
    return dict(wall_s=wall, first_line_s=first, max_rss_mib=rss)


def count_lines(paths) -> int:
    return sum(sum(1 for _ in open(p)) for p in paths)


def read_table(path: pathlib.Path) -> bytes:
    if path.name.endswith(".gz"):
        with gzip.open(path) as f:
            return f.read()
    return path.read_bytes()


def compare_tables(a: pathlib.Path, b: pathlib.Path) -> list[str]:
    """Names (relative paths) of the .csv / .csv.gz files that differ or exist on one side."""

    def tables(d):
        return {
            str(p.relative_to(d)) for p in d.rglob("*")
            if p.name.endswith((".csv", ".csv.gz")) and not p.name.startswith("timings")
        }  # fmt: skip

    ta, tb = tables(a), tables(b)
    diff = [f"{n} (old only)" for n in sorted(ta - tb)]
    diff += [f"{n} (new only)" for n in sorted(tb - ta)]
    diff += [n for n in sorted(ta & tb) if read_table(a / n) != read_table(b / n)]
    return diff


def compare_states(old_files, new_files) -> str:
    """The last run's decisions, old against new: the (k, state) of every window."""
    import json

    def states(files):
        out = []
        for i, f in enumerate(files):  # the i-th file of each side: the same dataset
            if not f.exists():
                out.append((i, "missing"))
                continue
            out += [(i, d.get("k"), d.get("state")) for d in map(json.loads, open(f))]
        return out

    a, b = states(old_files), states(new_files)
    if a == b:
        return f"same state at every window ({len(b)} windows)"
    pairs = [(x, y) for x, y in zip(a, b, strict=False) if x != y]
    n = len(pairs) + abs(len(a) - len(b))
    first = ""
    if pairs and len(pairs[0][0]) == 3 and len(pairs[0][1]) == 3:
        (i, k, so), (_, _, sn) = pairs[0]
        first = f", first: {new_files[i].stem} k={k} old {so}, new {sn}"
    return f"states differ at {n} of {max(len(a), len(b))} windows{first}"


class TimeUp(Exception):
    """``--stop-at`` reached: the runs left are skipped, what was measured is written."""


class Bench:
    def __init__(self, trees, tmp, repeats: int, csv_path, stop_at, datasets: int = 20):
        self.trees, self.tmp, self.repeats, self.csv_path = trees, tmp, repeats, csv_path
        self.stop_at, self.datasets = stop_at, datasets
        self.rows: list[dict] = []
        self.notes: dict[str, str] = {}

    def run(self, case, side, phase, rep, cmd, cache, first_line=False, extra=None) -> dict:
        if self.stop_at is not None and datetime.datetime.now() >= self.stop_at:
            raise TimeUp(f"{case} {side} {phase}#{rep} not started: --stop-at reached")
        tree = self.trees[side]
        logfile = self.tmp / "logs" / f"{case}_{side}_{phase}{rep}.out"
        logfile.parent.mkdir(exist_ok=True)
        r = timed(cmd, tree, side_env(tree, cache), logfile, first_line)
        row = dict(case=case, side=side, phase=phase, rep=rep, **r, load1=os.getloadavg()[0])
        row.update(extra(side) if extra else {})
        self.rows.append(row)
        write_rows(self.rows, self.csv_path)  # an interrupted run keeps what it measured
        first = "" if r["first_line_s"] is None else f", first line {r['first_line_s']:.1f} s"
        log(f"  {case} {side} {phase}#{rep}: {r['wall_s']:.1f} s{first}, "
            f"peak RSS {r['max_rss_mib']:.0f} MiB, load {load()}")  # fmt: skip
        return row

    # ---------------------------------------------------------------- cases
    def sweep(self) -> None:
        log("sweep: python -m experiments.sweep d_s=5,6,7 (cold only)")
        outs = {}
        for side in SIDES:
            outs[side] = self.tmp / f"sweep_{side}"
            cache = self.tmp / f"cache_sweep_{side}"
            hydra_dir = self.tmp / f"hydra_{side}"  # Hydra's own run folder, not in the tree
            cmd = [sys.executable, "-m", "experiments.sweep", "d_s=5,6,7", f"out={outs[side]}",
                   "figures=true", "progress=false", f"hydra.run.dir={hydra_dir}"]  # fmt: skip
            self.run("sweep", side, "cold", 1, cmd, cache)
        diff = compare_tables(outs["old"], outs["new"])
        n = sum(
            1 for p in outs["new"].rglob("*")
            if p.name.endswith((".csv", ".csv.gz")) and not p.name.startswith("timings")
        )  # fmt: skip
        self.notes["sweep"] = (
            f"tables identical ({n} .csv files but the timings)" if not diff
            else f"{len(diff)} of {n} tables differ: " + ", ".join(diff)
        )  # fmt: skip
        log(f"sweep: {self.notes['sweep']}")

    def office(self) -> None:
        if not OFFICE_IFC.exists():
            raise FileNotFoundError(OFFICE_IFC)
        data = self.tmp / "office_demo"
        wp = self.tmp / "wp.csv"
        wp.write_text(WAYPOINTS)
        log(f"office: simulating the dataset with the new code ({OFFICE_IFC.name})")
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-c", MFCL, "simulate", "--floorplan", str(OFFICE_IFC),
             "--trajectory", str(wp), "--out", str(data)],
            cwd=ROOT, env=side_env(ROOT, self.tmp / "cache_simulate"), check=True,
        )  # fmt: skip
        log(f"office: dataset written in {time.perf_counter() - t0:.1f} s")

        def windows(side):
            return dict(windows=count_lines([self.tmp / f"dec_{side}.jsonl"]))

        caches = {s: self.tmp / f"cache_office_{s}" for s in SIDES}
        for phase, reps in (("cold", 1), ("warm", self.repeats)):
            for rep in range(1, reps + 1):
                for side in SIDES:  # interleaved: a load change hits both sides
                    cmd = [sys.executable, "-c", MFCL, "localize", str(data),
                           "--out", str(self.tmp / f"dec_{side}.jsonl")]  # fmt: skip
                    self.run("office", side, phase, rep, cmd, caches[side], True, windows)
        self.notes["office"] = compare_states(
            [self.tmp / "dec_old.jsonl"], [self.tmp / "dec_new.jsonl"]
        )

    def many(self) -> None:
        data = self.tmp / "many_data"
        n = self.datasets
        log(f"many: writing {n} datasets (new tree's benchmarks/cli_many.make_datasets)")
        t0 = time.perf_counter()
        code = ("import sys, pathlib; sys.path.insert(0, 'benchmarks'); "
                "from cli_many import make_datasets; "
                f"print(len(make_datasets(pathlib.Path({str(data)!r}), {n})))")  # fmt: skip
        subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True,
                       env=side_env(ROOT, self.tmp / "cache_make"))  # fmt: skip
        log(f"many: datasets written in {time.perf_counter() - t0:.1f} s")

        def windows(side):
            return dict(windows=count_lines((self.tmp / f"many_{side}").glob("*.jsonl")))

        caches = {s: self.tmp / f"cache_many_{s}" for s in SIDES}
        for phase, reps in (("cold", 1), ("warm", self.repeats)):
            for rep in range(1, reps + 1):
                for side in SIDES:
                    out = self.tmp / f"many_{side}"
                    shutil.rmtree(out, ignore_errors=True)
                    cmd = [sys.executable, "-c", MFCL, "localize", str(data),
                           "--out-dir", str(out), "--quiet"]  # fmt: skip
                    self.run("many", side, phase, rep, cmd, caches[side], False, windows)
        new = sorted((self.tmp / "many_new").glob("*.jsonl"))
        self.notes["many"] = compare_states([self.tmp / "many_old" / p.name for p in new], new)


def _median(values) -> float:
    values = [v for v in values if v is not None and v == v]  # drops None and NaN
    return statistics.median(values) if values else float("nan")


def summarize(rows, notes) -> list[dict]:
    """Median per (case, phase, metric) and side; ratio old/new; peak resident memory (the
    maximum over the runs of that case and phase) per side."""
    import pandas as pd

    if not rows:
        return []
    df = pd.DataFrame(rows)
    last = df.groupby("case")["phase"].last().to_dict()
    out = []
    for (case, phase), g in df.groupby(["case", "phase"], sort=False):
        metrics = [("wall", "wall_s")]
        if "first_line_s" in g and g["first_line_s"].notna().any():
            metrics.append(("first status line", "first_line_s"))
        for label, col in metrics:
            med = {s: _median(g[g.side == s][col]) for s in SIDES}
            rss = {s: g[g.side == s]["max_rss_mib"].max() for s in SIDES}
            n = {s: int((g.side == s).sum()) for s in SIDES}
            note = [f"n={n['new']}" if n["old"] == n["new"] else f"n={n['old']} / {n['new']}"]
            if col == "wall_s":
                if "windows" in g and g["windows"].notna().any():
                    w = {s: g[g.side == s]["windows"].dropna() for s in SIDES}
                    w = {s: f"{int(v.iloc[0])}" if len(v) else "-" for s, v in w.items()}
                    note.append(f"{w['old']} / {w['new']} windows")
                if case in notes and phase == last[case]:  # compares the last runs' outputs
                    note.append(notes[case])
            out.append(dict(case=f"{case} {phase} ({label})", old=med["old"], new=med["new"],
                            ratio=med["old"] / med["new"] if med["new"] else float("nan"),
                            rss_old=rss["old"] if col == "wall_s" else float("nan"),
                            rss_new=rss["new"] if col == "wall_s" else float("nan"),
                            notes="; ".join(note)))  # fmt: skip
    return out


def write_rows(rows, csv_path: pathlib.Path) -> None:
    import pandas as pd

    csv_path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(csv_path, index=False, float_format="%.4g")


def _num(x: float, fmt: str) -> str:
    return "-" if x != x else format(x, fmt)  # NaN: "-"


def write_outputs(rows, summary, header: str, csv_path: pathlib.Path) -> pathlib.Path:
    """The CSV of every run, the Markdown table of medians and the figure; returns the
    Markdown's path."""
    write_rows(rows, csv_path)
    md = [header, "",
          "| case | old median s | new median s | ratio old/new | peak RSS old / new, MiB "
          "| notes |",
          "|:--|--:|--:|--:|--:|:--|"]  # fmt: skip
    md += [f"| {r['case']} | {_num(r['old'], '.1f')} | {_num(r['new'], '.1f')} | "
           f"{_num(r['ratio'], '.2f')} | "
           + ("" if r["rss_new"] != r["rss_new"] and r["rss_old"] != r["rss_old"]
              else f"{_num(r['rss_old'], '.0f')} / {_num(r['rss_new'], '.0f')}")
           + f" | {r['notes']} |"
           for r in summary]  # fmt: skip
    md_path = csv_path.with_suffix(".md")
    md_path.write_text("\n".join(md) + "\n")
    print("\n".join(md), flush=True)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np

        x = np.arange(len(summary))
        fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(summary) + 2), 4.2))
        ax.bar(x - 0.2, [r["old"] for r in summary], 0.4, label="old", color="#999999")
        ax.bar(x + 0.2, [r["new"] for r in summary], 0.4, label="new", color="#2b6cb0")
        for i, r in enumerate(summary):
            top = np.nanmax([r["old"], r["new"], 1e-3]) * 1.05
            ax.text(i, top, f"x{r['ratio']:.2f}", ha="center", fontsize=8)
        ax.set_xticks(x, [r["case"].replace(" (", "\n(") for r in summary], fontsize=7)
        ax.set_ylabel("median seconds")
        ax.set_yscale("log")
        ax.set_title("old vs new code, same machine, one run (label: old / new)", fontsize=10)
        ax.legend()
        fig.tight_layout()
        fig.savefig(csv_path.with_suffix(".png"), dpi=130)
        plt.close(fig)
    except Exception as e:  # the figure is optional
        log(f"figure not written: {e}")
    return md_path


def paste_into_docs(md_path: pathlib.Path, page: pathlib.Path) -> bool:
    """Pastes ``md_path`` into the ``<!-- BEGIN:bench_versions -->`` block of ``page`` (no
    other block of the page is touched)."""
    from mfcl_jax.study.readme import update_block

    return update_block(page, "bench_versions", md_path)


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

    started = datetime.datetime.now()
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
        f"{'' if a.datasets == 20 else f' --datasets {a.datasets}'}`, "
        f"{started:%Y-%m-%d %H:%M}; medians "
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
