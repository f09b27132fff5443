"""Front-end recall on the benchmark's nominal windows: corners alone, the full front-end on
the input odometry, and the default (with the LiDAR odometry).

``python -m experiments.frontend_recall [out_dir] [family ...]`` (logic in
``mfcl_jax.bench.recall``; about 13 min on 2 cores). A full run into the default ``results``
refreshes the README's generated recall block."""

import sys

from mfcl_jax.bench.recall import main
from mfcl_jax.study.readme import update_docs

if __name__ == "__main__":
    out = sys.argv[1] if len(sys.argv) > 1 else "results"
    main(out, sys.argv[2:] or None)
    if out == "results" and not sys.argv[2:]:
        names = update_docs("results")
        print(f"README and docs: refreshed {len(names)} generated tables")
