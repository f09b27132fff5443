"""What ``mfcl localize --early-commit`` costs a robot, against the default, in ONE run.

The README's Office_A walk (11 waypoints, simulated once with this tree's ``mfcl simulate``)
is localized by ``mfcl localize`` with the default (``ours``: commit on three scan-disjoint
windows) and with ``--early-commit ALPHA`` (the uniqueness lane of that error rate), the two
interleaved so that a change of the machine's load hits both: first with an empty
compilation cache each (cold), then ``--repeats`` times with the cache each filled (warm).
Per run: wall time from process start to exit, time to the first status line, peak resident
memory (``/usr/bin/time -v``), the window of the first COMMIT and whether the decisions agree
with the ground truth (``mfcl evaluate``: correct COMMIT windows / COMMIT windows).

Writes ``results/bench_early_commit.csv`` (one row per run) and ``.md`` (medians per policy
and phase). Usage: ``python benchmarks/early_commit.py [--alpha 1e-3] [--repeats 3]``
(about 5 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import pandas as pd

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from benchmarks._versions_cases import MFCL, OFFICE_IFC, WAYPOINTS  # noqa: E402
from benchmarks._versions_sides import ROOT, load, log, side_env, timed  # noqa: E402


def _first_commit(decisions: pathlib.Path) -> tuple[int | None, int]:
    """The window of the first COMMIT and the number of windows."""
    rows = [json.loads(x) for x in decisions.read_text().splitlines() if x.strip()]
    first = next((r["k"] for r in rows if r["state"] == "COMMIT"), None)
    return first, len(rows)


def _judged(data: pathlib.Path, decisions: pathlib.Path, env: dict) -> str:
    """``mfcl evaluate``'s verdict line (ground truth used to score only)."""
    r = subprocess.run([sys.executable, "-c", MFCL, "evaluate", str(data), "--decisions",
                        str(decisions)], cwd=ROOT, env=env, capture_output=True, text=True,
                       check=True)  # fmt: skip
    line = [x for x in r.stdout.splitlines() if x.startswith("verdict:")]
    return line[-1].removeprefix("verdict: ") if line else "?"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--alpha", default="1e-3", help="--early-commit ALPHA (1e-3)")
    ap.add_argument("--repeats", type=int, default=3, help="warm runs per policy (3)")
    ap.add_argument("--out", default=str(ROOT / "results" / "bench_early_commit"))
    a = ap.parse_args(argv)
    if not OFFICE_IFC.exists():
        raise SystemExit(f"early_commit: {OFFICE_IFC} not found (../shared/data)")
    out = pathlib.Path(a.out)
    policies = {"default": [], f"--early-commit {a.alpha}": ["--early-commit", a.alpha]}
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_early_") as tmp_name:
        tmp = pathlib.Path(tmp_name)
        data = tmp / "office_demo"
        (tmp / "wp.csv").write_text(WAYPOINTS)
        log(f"simulating the Office_A walk ({OFFICE_IFC.name})")
        subprocess.run([sys.executable, "-c", MFCL, "simulate", "--floorplan", str(OFFICE_IFC),
                        "--storey", "Level 1", "--trajectory", str(tmp / "wp.csv"),
                        "--odom-rate", "100", "--out", str(data)], cwd=ROOT,
                       env=side_env(ROOT, tmp / "cache_sim"), check=True,
                       capture_output=True)  # fmt: skip
        caches = {p: tmp / f"cache_{i}" for i, p in enumerate(policies)}
        for phase, reps in (("cold", 1), ("warm", a.repeats)):
            for rep in range(1, reps + 1):
                for i, (name, flags) in enumerate(policies.items()):
                    dec = tmp / f"dec_{i}.jsonl"
                    env = side_env(ROOT, caches[name])
                    cmd = [sys.executable, "-c", MFCL, "localize", str(data), "--out", str(dec),
                           *flags]  # fmt: skip
                    r = timed(cmd, ROOT, env, tmp / f"run_{i}_{phase}{rep}.out", True)
                    first, n = _first_commit(dec)
                    row = dict(policy=name, phase=phase, rep=rep, **r, windows=n,
                               first_commit=first, verdict=_judged(data, dec, env),
                               load1=os.getloadavg()[0])  # fmt: skip
                    rows.append(row)
                    log(
                        f"  {name} {phase}#{rep}: {r['wall_s']:.1f} s, first line "
                        f"{r['first_line_s']:.1f} s, first commit k={first}, load {load()}"
                    )
    df = pd.DataFrame(rows)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    med = df.groupby(["policy", "phase"], sort=False).agg(
        runs=("wall_s", "size"), first_line_s=("first_line_s", "median"),
        wall_s=("wall_s", "median"), peak_rss_mib=("max_rss_mib", "max"),
        first_commit=("first_commit", "first"), verdict=("verdict", "first"),
    ).reset_index()  # fmt: skip
    note = (
        f"\n\nOne run of `benchmarks/early_commit.py --alpha {a.alpha} --repeats "
        f"{a.repeats}`: medians; {os.cpu_count()} cores; load average {load()} at the end.\n"
    )
    out.with_suffix(".md").write_text(med.to_markdown(index=False, floatfmt=".1f") + note)
    print(med.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
