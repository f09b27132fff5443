"""Which storey am I on: ``python -m experiments.storeys [--quick] [--out results/storeys]``.

Decides walks on the tower family and on the real multi-storey IFC models against the whole
building, and the same walks against a wrong storey's plan alone (logic in
``mfcl_jax.study.storeys``); writes ``runs.csv`` (one row per walk), ``summary.md`` and
``timing.md`` under ``--out``. A full run into the default folder refreshes the generated
tables of ``docs/storeys.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m experiments.storeys", description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("results/storeys"))
    ap.add_argument("--quick", action="store_true", help="one seed, no IFC models (a check)")
    ap.add_argument("--seeds", type=int, default=3, help="towers per kind (default 3)")
    ap.add_argument("--storeys", type=int, default=4, help="storeys per tower (default 4)")
    ap.add_argument("--tours", type=int, default=2, help="tours per IFC storey (default 2)")
    args = ap.parse_args(argv)

    import pandas as pd

    from mfcl_jax.io.atomic import atomic_write_text
    from mfcl_jax.robot.progress import Progress
    from mfcl_jax.sim.families.tower import TOWER_KINDS
    from mfcl_jax.sources.data import data_dir
    from mfcl_jax.study import storeys as S

    progress = Progress(sys.stderr.isatty())
    t0 = time.perf_counter()
    seeds = range(1 if args.quick else args.seeds)
    walks = S.tower_walks(TOWER_KINDS, seeds, args.storeys)
    data = data_dir()
    if not args.quick and data.is_dir():
        walks += S.ifc_walks(data, args.tours)
    wrong, left_out = S.wrong_storey(walks)
    t_sim = time.perf_counter() - t0
    print(f"{len(walks)} walks and {len(wrong)} wrong-storey runs simulated in {t_sim:.0f} s",
          file=sys.stderr)  # fmt: skip
    every = walks + wrong
    records, t_dec = S.decide_walks(every, progress)
    rows = pd.DataFrame([S.judge(w, r, S.tells_apart(w))
                         for w, r in zip(every, records, strict=True)])  # fmt: skip
    table = S.summary_table(rows)
    n_win = int(rows["windows"].sum())
    timing = pd.DataFrame([
        {"stage": "buildings and walks (simulated)", "seconds": round(t_sim, 1)},
        {"stage": f"decided ({len(every)} runs, {n_win} windows)", "seconds": round(t_dec, 1)},
    ])  # fmt: skip
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "runs.csv", rows.to_csv(index=False))
    atomic_write_text(out / "summary.md", table.to_markdown(index=False, floatfmt=".1f")
                      + "\n\nWrong-storey runs left out (no other storey differs where the "
                      f"walk passes): {left_out}\n")  # fmt: skip
    atomic_write_text(out / "timing.md", timing.to_markdown(index=False) + "\n")
    print(table.to_markdown(index=False, floatfmt=".1f"))
    print(f"wrong-storey runs left out (no other storey differs where the walk passes): "
          f"{left_out}")  # fmt: skip
    print(timing.to_markdown(index=False))
    false = int((rows["commit_false"] > 0).sum())
    print(f"walks with a false commit: {false}")
    if out == Path("results/storeys") and not args.quick:
        from mfcl_jax.study.readme import update_block

        update_block("docs/storeys.md", "storeys/summary", out / "summary.md")
        print("docs/storeys.md: refreshed its table")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
