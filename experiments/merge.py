"""Merge a Hydra multirun of the sweep: ``python -m experiments.merge multirun/DATE/TIME [out]``."""

from __future__ import annotations

import sys
from pathlib import Path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print("usage: python -m experiments.merge MULTIRUN_DIR [OUT_DIR]", file=sys.stderr)
        return 2
    root = Path(argv[0])
    out = Path(argv[1]) if len(argv) > 1 else Path("results")
    from mfcl_jax.study.run import MergeError, merge

    jobs = sorted(p.parent.parent for p in root.glob("**/raw/windows.csv.gz"))
    if not jobs:
        print(f"merge: no job outputs (raw/windows.csv.gz) under {root}", file=sys.stderr)
        return 1
    try:
        tabs = merge(jobs, out)
    except MergeError as e:
        print(e, file=sys.stderr)
        return 1
    print(f"merged {len(jobs)} jobs into {len(tabs)} tables in {out}/")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
