"""``mfcl localize FOLDER`` on a folder of held-out-like datasets: time and peak memory.

The datasets are the benchmark's nominal runs (``bench.suite.nominal_recordings``: procedural
buildings of every family, IFC tours, real laser-log windows against held-out maps, the Intel
bag), taken family by family in turn and written once as dataset folders under ``--work``.
The command a user runs is then timed as a process: ``mfcl localize WORK/datasets --out-dir
WORK/out --quiet`` (its peak resident memory from the kernel's accounting of the child,
``getrusage``), with ``--max-memory`` passed on when given.

    python benchmarks/batch_memory.py --datasets 64 [--max-memory 6G] [--paste]

Prints and saves ``results/bench_batch_memory.md`` (one row per call: datasets, windows,
wall time, peak memory, exit status).
"""

from __future__ import annotations

import argparse
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _datasets(n: int, work: Path) -> Path:
    """``n`` dataset folders under ``work/datasets`` (written once, reused)."""
    from mfcl_jax.bench.config import BenchmarkConfig
    from mfcl_jax.bench.suite import nominal_recordings
    from mfcl_jax.score import pose_at
    from mfcl_jax.sources.dataset_write import write_dataset

    out = work / "datasets"
    have = (
        sorted(p for p in out.glob("*") if (p / "odometry.tum").is_file()) if out.is_dir() else []
    )
    if len(have) >= n:
        for extra in have[n:]:
            shutil.rmtree(extra)
        return out
    cfg = BenchmarkConfig(seeds=2, walks=2, ifc_walks=2, log_windows=4, progress=True)
    recs = nominal_recordings(cfg)
    by_family: dict = {}
    for r in recs:
        by_family.setdefault(r.meta.get("family"), []).append(r)
    order, i = [], 0
    while len(order) < n and any(i < len(v) for v in by_family.values()):
        order += [v[i] for v in by_family.values() if i < len(v)]
        i += 1
    shutil.rmtree(out, ignore_errors=True)
    for j, r in enumerate(order[:n]):
        gt = pose_at(r.truth.times, r.truth.poses, r.seq.times)
        name = f"{j:03d}_" + r.name.replace("/", "_").replace(":", "_")
        write_dataset(out / name, r.floorplan, r.seq.times, r.seq.scans, r.seq.odometry,
                      groundtruth=gt)  # fmt: skip
        print(f"wrote {out / name}", file=sys.stderr, flush=True)
    return out


def _run(datasets: Path, work: Path, max_memory: str | None) -> dict:
    out = work / "out"
    shutil.rmtree(out, ignore_errors=True)
    cmd = [str(Path(sys.executable).parent / "mfcl"), "localize", str(datasets), "--out-dir",
           str(out), "--quiet", "--keep-going"]  # fmt: skip
    if max_memory:
        cmd += ["--max-memory", max_memory]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    written = sorted(out.glob("*.jsonl")) if out.is_dir() else []
    windows = sum(len(p.read_text().splitlines()) for p in written)
    n = len([p for p in datasets.iterdir() if p.is_dir()])
    tail = (r.stderr.strip().splitlines() or [""])[-1]
    return dict(datasets=n, decided=len(written), windows=windows, wall_s=round(wall, 1),
                peak_gib=round(peak_kib / 2**20, 2), exit=r.returncode,
                max_memory=max_memory or "default", last_line=tail[:120])  # fmt: skip


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--datasets", type=int, default=64)
    ap.add_argument("--work", type=Path, default=Path("/tmp/mfcl_batch_memory"))
    ap.add_argument("--max-memory", help="passed to mfcl localize (e.g. 6G)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_batch_memory.md")
    args = ap.parse_args(argv)
    datasets = _datasets(args.datasets, args.work)
    row = _run(datasets, args.work, args.max_memory)
    import pandas as pd

    table = pd.DataFrame([row]).to_markdown(index=False)
    print(table)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        "# mfcl localize on a folder of held-out-like datasets\n\n"
        "`python benchmarks/batch_memory.py --datasets "
        f"{args.datasets}" + (f" --max-memory {args.max_memory}" if args.max_memory else "")
        + "` (peak: the process's resident memory, from getrusage)\n\n" + table + "\n"
    )  # fmt: skip
    return 0 if row["exit"] in (0, 2) else 1


if __name__ == "__main__":
    sys.exit(main())
