"""How close the benchmark's right commits came to the false-commit line, from a finished run's
``windows.csv.gz``: ``python -m experiments.margins [results/benchmark ...]``. Run on the
default folder, it refreshes the README's generated block (as the benchmark does)."""

from __future__ import annotations

import sys
from pathlib import Path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    from mfcl_jax.bench.main import write_margins

    for d in argv or ["results/benchmark"]:
        try:
            tab = write_margins(Path(d))
        except FileNotFoundError as e:
            print(e, file=sys.stderr)
            return 1
        print(f"{d}/margins.md")
        print(tab.to_markdown(index=False, floatfmt=".3g"))
    if not argv:
        from mfcl_jax.study.readme import update_docs

        names = update_docs("results")
        print(f"README and docs: refreshed {len(names)} generated tables")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
