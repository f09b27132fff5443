"""One picture per building family (seed 0 unless told):
``python -m experiments.plot_families --out results/benchmark/families``."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mfcl_jax.report.plots_scene import plot_family
from mfcl_jax.sim.families import FAMILIES, make_scene


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="results/benchmark/families")
    ap.add_argument("--families", nargs="+", default=list(FAMILIES), choices=list(FAMILIES))
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    for family in args.families:
        t0 = time.perf_counter()
        scene = make_scene(family, args.seed)
        dt = time.perf_counter() - t0
        suffix = "" if args.seed == 0 else f"-{args.seed}"
        out = plot_family(scene, Path(args.out) / f"{family}{suffix}.png")
        print(f"{out}  (built in {dt:.3f} s)")


if __name__ == "__main__":
    main()
