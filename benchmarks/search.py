"""The path search's kernels, old code against new, timed in ONE run.

What it times, per building (compile time apart, medians of ``--repeats`` calls after one
warm-up): the rival search (``decision.rivals.search``: the whole path placed anywhere in the
plan, 72 headings by FFT, then the polish of the best peaks) and the uniqueness test's fit of
16 placements under the path's likelihood (``frontend.path_llr.refine``, vmapped), on a
synthetic path of 2,048 returns and free samples spread over the building's rooms (the
kernels' cost does not depend on where the points fall, only on how many there are and on
the plan's grid). The fit runs the lane's polish rounds (``UniqueParams.polish`` where the
side has it: since ``ff373ca`` a first round of 0.3 m / 3 deg before the three of
``path_llr.REFINE_STEPS``), so against ``ff373ca`` its ratio is that round's cost.
Where the side has it, the edge of the best placement's own peak (``uniqueness.edge``: 12
placements just past its 1 m / 5 deg line evaluated, the best 3 fitted while they stay
outside it) is timed too.
Buildings: the stand-in ``three_rooms``, the Office_A IFC storey and the Willow Garage map
(the benchmark's largest grid).

Each side (the OLD git ref, default ``ff373ca``, checked out into a temporary worktree; the NEW
working tree) runs as a subprocess of this Python with its own tree first on ``PYTHONPATH``;
the two alternate building by building so that load drifts hit both alike. Both sides'
outputs are compared (the best placement and the scores, to 1e-4) and the header says, per
kernel, whether they agree: a kernel whose code changed need not.

Writes ``results/bench_search.csv`` (one row per side x building x kernel),
``results/bench_search.md`` (medians and the ratio old/new, pasted into the
``<!-- BEGIN:bench_search -->`` block of ``docs/speed.md``) and ``results/bench_search.png``.

Usage: ``python benchmarks/search.py [--old REF] [--repeats 7]`` (about 3 minutes).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

from mfcl_jax.sources.data import data_dir

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
DATA = data_dir()
BUILDINGS = ("three_rooms", "office_a", "willow")

# Run inside each side's tree: only APIs both sides share (rivals.search, path_llr,
# uniqueness.DEFAULT_UNIQUE).
CHILD = r"""
import json, sys, time
import jax, jax.numpy as jnp, numpy as np
from mfcl_jax.decision import rivals
from mfcl_jax.frontend import path_llr

name, repeats, data = sys.argv[1], int(sys.argv[2]), sys.argv[3]
if name == "three_rooms":
    from mfcl_jax.sim.scenes import get_scene
    fp = get_scene("three_rooms").floorplan
elif name == "office_a":
    from mfcl_jax.floorplan import load_floorplan
    fp = load_floorplan(data + "/ifc/Office_A_20110811.ifc", storey="Level 1")
else:
    from mfcl_jax.floorplan import load_floorplan
    fp = load_floorplan(data + "/maps/willow-full.yaml")
rp = rivals.DEFAULT_RIVALS
fields = jax.tree.map(lambda a: jnp.asarray(a)[0], rivals.stack_fields([fp], rp))
n_img = rivals.image_size([fp], rp)
rng = np.random.default_rng(0)
# a path through the building: points spread over the rooms' bounding box
lo, hi = np.asarray(fp.bounds[:2], float), np.asarray(fp.bounds[2:], float)
C, P = 32, 64  # windows x evidence samples
orig = rng.uniform(lo, hi, (C, 1, 2)).repeat(P, 1)
pts = orig + rng.normal(0.0, 3.0, (C, P, 2))
ev_p = jnp.asarray(pts, jnp.float32)
ev_o = jnp.asarray(orig, jnp.float32)
ev_m = jnp.ones((C, P), bool)
X = jnp.zeros((C, 3), jnp.float32)

search = jax.jit(lambda a, b, m, x: rivals.search(a, b, m, x, fields, n_img, rp))
pe = path_llr.path_evidence(ev_p, ev_o, ev_m, X, 60.0)
cand = jnp.asarray(np.column_stack([rng.uniform(lo, hi, (16, 2)),
                                    rng.uniform(-3, 3, 16)]), jnp.float32)
# the uniqueness lane's fit: its own polish rounds where it names them (UniqueParams.polish)
from mfcl_jax.decision import uniqueness
U = uniqueness.DEFAULT_UNIQUE
kw = dict(steps=U.polish) if hasattr(U, "polish") else {}
fit = jax.jit(lambda c: jax.vmap(lambda a: path_llr.refine(a, pe, fields, U.llr, **kw))(c))
kernels = [("rival search", search, (ev_p, ev_o, ev_m, X)), ("path fit x16", fit, (cand,))]
if hasattr(uniqueness, "edge"):  # the edge of A*'s own peak: 3 fits that stay outside it
    edge = jax.jit(lambda a, x: uniqueness.edge(a, x, pe, fields, U))
    kernels.append(("edge of the peak", edge, (cand[0], X[-1])))
out = {}
for kernel, f, args in kernels:
    t0 = time.perf_counter(); r = jax.block_until_ready(f(*args))
    compile_s = time.perf_counter() - t0
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(*args))
        ts.append(time.perf_counter() - t0)
    out[kernel] = dict(compile_s=compile_s, median_ms=float(np.median(ts)) * 1e3,
                       result=[np.asarray(x, np.float64).round(5).tolist() for x in r])
print("RESULT " + json.dumps(dict(building=name, grid=list(fields.hit.shape), n_img=n_img,
                                  kernels=out)))
"""


def run_side(tree: pathlib.Path, building: str, repeats: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "JAX_PLATFORMS": "cpu"}
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    r = subprocess.run([sys.executable, "-c", CHILD, building, str(repeats), str(DATA)],
                       cwd=tree, env=env, capture_output=True, text=True)  # fmt: skip
    if r.returncode != 0:
        raise RuntimeError(f"{tree} {building}: exit {r.returncode}\n{r.stderr[-2000:]}")
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("RESULT ")][-1]
    return json.loads(line[len("RESULT ") :])


def same(a, b, tol=1e-4) -> bool:
    import numpy as np

    return all(
        np.allclose(np.asarray(x, float), np.asarray(y, float), atol=tol, equal_nan=True)
        for x, y in zip(a, b, strict=True)
    )


def main(argv=None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", default="ff373ca")
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        old = pathlib.Path(tmp) / "old"
        subprocess.run(["git", "worktree", "add", "--detach", str(old), a.old], cwd=ROOT,
                       check=True, capture_output=True)  # fmt: skip
        os.symlink(ROOT.parent / "shared", pathlib.Path(tmp) / "shared")
        try:
            for b in BUILDINGS:
                res = {side: run_side(tree, b, a.repeats) for side, tree in
                       (("old", old), ("new", ROOT))}  # fmt: skip
                for kernel in res["new"]["kernels"]:
                    # a kernel the old side lacks: its old row is empty
                    none = dict(result=None, median_ms=float("nan"), compile_s=float("nan"))
                    ko = res["old"]["kernels"].get(kernel, none)
                    agree = ko["result"] is not None and same(
                        ko["result"], res["new"]["kernels"][kernel]["result"]
                    )
                    for side, k in (("old", ko), ("new", res["new"]["kernels"][kernel])):
                        rows.append(dict(building=b, grid="x".join(map(str, res[side]["grid"])),
                                         kernel=kernel, side=side, median_ms=k["median_ms"],
                                         compile_s=k["compile_s"], agree=agree))  # fmt: skip
                    print(
                        f"{b:12s} {kernel:14s} old {rows[-2]['median_ms']:7.1f} ms  new "
                        f"{rows[-1]['median_ms']:7.1f} ms  agree={agree}",
                        flush=True,
                    )
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(old)], cwd=ROOT,
                           capture_output=True)  # fmt: skip
    df = pd.DataFrame(rows)
    RESULTS.mkdir(exist_ok=True)
    df.to_csv(RESULTS / "bench_search.csv", index=False)
    wide = df.pivot_table(index=["building", "grid", "kernel"], columns="side",
                          values=["median_ms", "compile_s"]).reset_index()  # fmt: skip
    table = pd.DataFrame({
        "building": wide["building"], "grid": wide["grid"], "kernel": wide["kernel"],
        "old ms": wide[("median_ms", "old")].round(1),
        "new ms": wide[("median_ms", "new")].round(1),
        "old/new": (wide[("median_ms", "old")] / wide[("median_ms", "new")]).round(2),
        "compile s old / new": [f"{o:.1f} / {n:.1f}" for o, n in
                                zip(wide[("compile_s", "old")], wide[("compile_s", "new")],
                                    strict=True)],
    })  # fmt: skip
    agree = df.groupby("kernel")["agree"].all()
    head = (
        f"Old code ({a.old}) vs new code (the working tree), one run of `benchmarks/"
        f"search.py --repeats {a.repeats}`; "
        f"medians of {a.repeats} calls after one warm-up, the sides alternating building by "
        f"building; load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} at the "
        f"end; results agree to 1e-4: "
        + "; ".join(f"{k}: {'yes' if v else 'no'}" for k, v in agree.items())
        + "."
    )
    md = head + "\n\n" + table.to_markdown(index=False) + "\n"
    (RESULTS / "bench_search.md").write_text(md)
    print("\n" + md)
    page = ROOT / "docs" / "speed.md"
    from mfcl_jax.study.readme import update_block

    update_block(page, "bench_search", RESULTS / "bench_search.md")
    fig, ax = plt.subplots(figsize=(7, 3.2))
    labels = [f"{r.building}\n{r.kernel}" for r in table.itertuples()]
    x = range(len(table))
    ax.bar([i - 0.2 for i in x], table["old ms"], 0.4, label=f"old ({a.old})")
    ax.bar([i + 0.2 for i in x], table["new ms"], 0.4, label="new")
    ax.set_xticks(list(x), labels, fontsize=7)
    ax.set_ylabel("ms per call (median)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "bench_search.png", dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
