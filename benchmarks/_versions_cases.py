"""The cases of ``benchmarks/versions.py`` (``sweep``, ``office``, ``many``): each run of each
side timed in turn, a row per run written as it comes, the two sides' outputs compared."""

from __future__ import annotations

import datetime
import os
import shutil
import subprocess
import sys
import time

from benchmarks._versions_compare import compare_states, compare_tables, count_lines
from benchmarks._versions_report import write_rows
from benchmarks._versions_sides import ROOT, SIDES, load, log, side_env, timed
from mfcl_jax.sources.data import data_dir

OFFICE_IFC = data_dir() / "ifc" / "Office_A_20110811.ifc"
WAYPOINTS = (
    "x,y\n6,-27\n6.9,-15.1\n6.9,-13.5\n25.2,-13.5\n25.2,-15.1\n25.4,-29.3\n25.4,-30.9\n"
    "20.3,-30.8\n27.7,-30.8\n27.7,-29.2\n33.8,-29.4\n"
)
MFCL = "import sys; from mfcl_jax.cli import main; sys.exit(main())"


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
             "--storey", "Level 1", "--trajectory", str(wp), "--out", str(data)],
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
