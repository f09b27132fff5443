"""Many datasets in one ``mfcl localize`` call, as a user runs it (a subprocess, cold and warm).

Writes 20 simulated dataset folders (the procedural families' walks, 18-37 windows each) into a
temporary folder, then times ``mfcl localize FOLDER --out-dir OUT --quiet`` twice: with an
empty persistent compilation cache (cold: every kernel compiles) and again with the cache the
first call filled (warm: a second run on the same machine). Wall time of the whole command,
from process start to exit. Writes ``results/bench_cli.csv``.
Usage: ``python benchmarks/cli_many.py [--datasets 20]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import pandas as pd

ROOT = pathlib.Path(__file__).resolve().parents[1]


def make_datasets(root: pathlib.Path, n: int) -> list[str]:
    from mfcl_jax.sim import families
    from mfcl_jax.sources.simulated import simulate_dataset

    names = []
    order = [(f, w) for w in ("C", "B", "A") for f in families.FAMILIES]
    for i, (fam, walk) in enumerate(order[:n]):
        scene = families.make_scene(fam, 0)
        name = f"{fam}_{walk}"
        simulate_dataset(scene.floorplan, scene.trajectories[walk], root / name, seed=i)
        names.append(name)
    return names


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--datasets", type=int, default=20)
    ap.add_argument("--out", default=str(ROOT / "results" / "bench_cli.csv"))
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        t0 = time.perf_counter()
        names = make_datasets(tmp / "data", a.datasets)
        print(f"{len(names)} datasets written in {time.perf_counter() - t0:.1f} s", flush=True)
        env = {**os.environ, "MFCL_CACHE_DIR": str(tmp / "cache")}
        for label in ("cold", "warm"):
            out = tmp / f"out_{label}"
            cmd = ["mfcl", "localize", str(tmp / "data"), "--out-dir", str(out), "--quiet"]
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
            wall = time.perf_counter() - t0
            windows = sum(sum(1 for _ in open(f)) for f in out.glob("*.jsonl"))
            rows.append(dict(case=label, datasets=len(names), windows=windows, wall_s=wall,
                             ms_per_window=1e3 * wall / max(windows, 1),
                             load1=os.getloadavg()[0]))  # fmt: skip
            print(f"{label}: {len(names)} datasets, {windows} windows, {wall:.1f} s", flush=True)
    df = pd.DataFrame(rows)
    pathlib.Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(a.out, index=False, float_format="%.4g")
    print(df.to_markdown(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
