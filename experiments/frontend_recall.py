"""Front-end recall on the benchmark's nominal windows: corners alone, the full front-end on
the input odometry, and the default (with the LiDAR odometry).

``python -m experiments.frontend_recall [out_dir] [family ...]`` (logic in
``mfcl_jax.bench.recall``; about 8 min on 2 cores)."""

import sys

from mfcl_jax.bench.recall import main

if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results", sys.argv[2:] or None)
