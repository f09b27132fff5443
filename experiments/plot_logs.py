"""Pictures of the real-log benchmark windows with their held-out maps, one per log:
``python -m experiments.plot_logs --out results/benchmark/families`` writes ``log-<name>.png``
and ``bag-intel.png`` (all windows of a log side by side) and prints the time per window."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mfcl_jax.report.plots_logs import plot_log_recording
from mfcl_jax.sources.logs import LOGS, bag_recordings, log_recordings


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="results/benchmark/families")
    ap.add_argument("--windows", type=int, default=3)
    ap.add_argument("--length", type=float, default=60.0)
    ap.add_argument("--res", type=float, default=0.10)
    ap.add_argument("--cache-dir", default=None)
    args = ap.parse_args(argv)
    out = Path(args.out)
    kw = dict(length_m=args.length, map_res=args.res, cache_dir=args.cache_dir)
    jobs = [(f"log-{n}", lambda n=n: log_recordings(n, args.windows, **kw)) for n in LOGS]
    jobs.append(("bag-intel", lambda: bag_recordings(args.windows, **kw)))
    for stem, make in jobs:
        t0 = time.perf_counter()
        recs = make()
        dt = (time.perf_counter() - t0) / len(recs)
        png = plot_log_recording(recs, out / f"{stem}.png")
        print(f"{stem}: {len(recs)} windows, {dt:.1f} s per window; wrote {png}")


if __name__ == "__main__":
    main()
