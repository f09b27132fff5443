"""Merge a Hydra multirun of the benchmark:
``python -m experiments.merge_benchmark multirun/benchmark/DATE/TIME [OUT_DIR]``."""

from __future__ import annotations

import sys
from pathlib import Path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(
            "usage: python -m experiments.merge_benchmark MULTIRUN_DIR [OUT_DIR]", file=sys.stderr
        )
        return 2
    root = Path(argv[0])
    out = Path(argv[1]) if len(argv) > 1 else Path("results/benchmark")
    from mfcl_jax.bench.config import BenchmarkError
    from mfcl_jax.bench.main import merge

    jobs = sorted(p.parent for p in root.glob("*/runs.csv"))
    if not jobs:
        print(f"merge_benchmark: no job outputs (*/runs.csv) under {root}", file=sys.stderr)
        return 1
    try:
        tabs = merge(jobs, out)
    except BenchmarkError as e:
        print(e, file=sys.stderr)
        return 1
    print(f"merged {len(jobs)} jobs into {len(tabs)} tables in {out}/")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
