"""The plan searches' FFT correlation at ``path_search.corr_size`` against a whole image of
padding (``side + n_img``, rounded to a fast length where it was: the size before), in one
run.

The kernel timed is the one the dense front-end, the path search and the evidence grid run per
heading: two real forward transforms of a point image, their products with a plan field's
spectrum, one inverse. Shapes: the dense front-end (96-cell image at 0.4 m, 12 headings, a
small and a 51 m plan) and the evidence grid (128-cell image at 0.3 m, 72 headings, the
smallest benchmark plan and a 51 m square). Compilation is timed apart; medians of
``--repeats`` runs. Writes ``results/bench_correlation.csv`` and ``.md`` (pasted into the
``<!-- BEGIN:bench_correlation -->`` block of ``docs/speed.md``).

Usage: ``python benchmarks/correlation.py [--repeats 9]``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np
import pandas as pd

ROOT = pathlib.Path(__file__).resolve().parents[1]
# (what, plan side in cells (rows, cols), image side, headings, whether the size before was
# rounded to a fast length: the path search's and the grid's were, the dense front-end's not)
CASES = (
    ("dense front-end, small plan", (48, 80), 96, 12, False),
    ("dense front-end, 51 m plan", (128, 128), 96, 12, False),
    ("evidence grid, smallest plan", (52, 160), 128, 72, True),
    ("evidence grid, 51 m plan", (171, 171), 128, 72, True),
)


def _kernel(side, n, size, heads):
    import jax
    import jax.numpy as jnp

    rng = np.random.default_rng(0)
    field = jnp.asarray(rng.random(side), jnp.float32)
    spec_f = jnp.fft.rfft2(field, size)

    @jax.jit
    def run(imgs):
        def one(img):
            s = spec_f * jnp.conj(jnp.fft.rfft2(img, size))
            s = s - spec_f * jnp.conj(jnp.fft.rfft2(img * 0.5, size))
            return jnp.max(jnp.fft.irfft2(s, size))

        return jax.lax.map(one, imgs)

    imgs = jnp.asarray(rng.random((heads, n, n)), jnp.float32)
    return run, imgs


def _time(side, n, size, heads, repeats):
    import jax

    run, imgs = _kernel(side, n, size, heads)
    t0 = time.perf_counter()
    jax.block_until_ready(run(imgs))
    first = time.perf_counter() - t0
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run(imgs))
        ts.append(time.perf_counter() - t0)
    med = float(np.median(ts))
    return med * 1e3, max(first - med, 0.0)


def main(argv=None) -> int:
    from mfcl_jax.frontend.path_search import corr_size, fft_size
    from mfcl_jax.study.readme import update_block

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--out", default=str(ROOT / "results" / "bench_correlation"))
    a = ap.parse_args(argv)
    rows = []
    for what, side, n, heads, rounded in CASES:
        sizes = {"whole image": tuple(fft_size(s + n) if rounded else s + n for s in side),
                 "corr_size": tuple(corr_size(s, n) for s in side)}  # fmt: skip
        # the two sizes alternate, twice, so that a drift of the machine's speed shows
        for rep in range(2):
            for label, size in sizes.items():
                ms, comp = _time(side, n, size, heads, a.repeats)
                rows.append(dict(case=what, plan=f"{side[0]} x {side[1]}", image=n,
                                 headings=heads, padding=label, fft=f"{size[0]} x {size[1]}",
                                 round=rep, ms=round(ms, 2), compile_s=round(comp, 2)))  # fmt: skip
                print(f"{what}: {label} {size}: {ms:.1f} ms (compile {comp:.1f} s)", flush=True)
    df = pd.DataFrame(rows)
    out = pathlib.Path(a.out)
    df.to_csv(out.with_suffix(".csv"), index=False)
    med = df.groupby(["case", "plan", "image", "headings", "padding", "fft"], sort=False)["ms"]
    t = med.median().reset_index()
    wide = t.pivot_table(index=["case", "plan", "image", "headings"], columns="padding",
                         values="ms", sort=False).reset_index()  # fmt: skip
    ffts = t.pivot_table(index="case", columns="padding", values="fft", aggfunc="first",
                         sort=False)  # fmt: skip
    wide["fft before"] = wide["case"].map(ffts["whole image"])
    wide["fft now"] = wide["case"].map(ffts["corr_size"])
    wide["ratio"] = (wide["whole image"] / wide["corr_size"]).round(2)
    wide = wide.rename(columns={"whole image": "ms before", "corr_size": "ms now"})
    cols = ["case", "plan", "image", "headings", "fft before", "ms before", "fft now", "ms now",
            "ratio"]  # fmt: skip
    with open("/proc/loadavg") as f:
        load = " ".join(f.read().split()[:3])
    head = f"Per call (every heading of one window), medians of {a.repeats} x 2 rounds; "
    text = f"{head}load average {load} at the end.\n\n{wide[cols].to_markdown(index=False)}\n"
    out.with_suffix(".md").write_text(text)
    print(text)
    if out.parent == ROOT / "results":
        update_block(ROOT / "docs" / "speed.md", "bench_correlation", out.with_suffix(".md"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
