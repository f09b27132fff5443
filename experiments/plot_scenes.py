"""Figure of the built-in scenes: ``python -m experiments.plot_scenes --out results/scenes.png``."""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from mfcl_jax.report.plots_scene import plot_scenes  # noqa: E402
from mfcl_jax.sim.scenes import SCENES, get_scene  # noqa: E402


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="results/scenes.png")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    args = ap.parse_args(argv)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    plot_scenes([get_scene(n) for n in args.scenes], out=args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
