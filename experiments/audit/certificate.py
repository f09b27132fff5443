"""Does the uniqueness test's grid search miss a competitor where a lane commits on it?
``python -m experiments.audit.certificate [out] [lanes]`` (default ``results/certificate_audit``,
lanes ``ours_unique,ours_unique_a2``).

The uniqueness lanes (``decision.uniqueness``) commit when the best placement ``A*`` of the
path beats every competitor their grid search finds by ``log(1 / alpha)``; the search is
exhaustive on a grid (5 deg, 0.4-0.5 m cells, then polished), not over the continuum. This
audit takes every nominal run of the default benchmark (``results/benchmark/windows.csv.gz``)
where a lane commits before ``ours`` does (the commit rests on the test, not on the count of
windows), rebuilds the path evidence of that window from the recording (the windows and the
evidence sample the layer reads, the path length by the refined odometry), polishes ``A*``
under it from the committed pose, and runs the branch and bound (``path_certify``) over
every placement outside ``A*``'s neighbourhood for one within ``log(1 / alpha)`` of it:

* ``certified``: none exists (the commit holds under the observation model, whatever the grid);
* ``competitor``: one exists (with its margin; the grid search missed it, or the rebuilt
  evidence differs from the layer's): ``near`` when it places the robot within 2 m and 10 deg
  of ``A*`` (the same place, a little past the 1 m / 5 deg line), ``far`` otherwise;
* ``open``: the search could neither (a cell budget or its finest cells).

Ground truth is read only to say whether the commit was right. Writes ``tests.csv`` (one row
per test) and ``summary.md`` (pasted into ``docs/benchmark.md`` when written to the default
folder); 1-90 s per test on two cores, about 23 minutes for the two lanes, at a peak of 18 GB
of memory (run it alone).
"""

from __future__ import annotations

import math
import sys
import time
from functools import partial
from pathlib import Path

import jax
import numpy as np
import pandas as pd

from mfcl_jax.se2 import wrap_host

LANES = {"ours_unique": 1e-3, "ours_unique_a1": 1e-1, "ours_unique_a2": 1e-2,
         "ours_unique_a4": 1e-4, "ours_unique_a6": 1e-6}  # fmt: skip


def tests_of(windows: pd.DataFrame, lanes) -> pd.DataFrame:
    """The (run, lane, window) where a lane's first commit comes before ours' first commit."""
    w = windows[windows.fault.isna() & windows.policy.isin([*lanes, "ours"])]
    first = w[w.state == "COMMIT"].groupby(["name", "policy"]).k.min().unstack("policy")
    rows = []
    for lane in lanes:
        if lane not in first:
            continue
        ours = first["ours"] if "ours" in first else pd.Series(np.inf, index=first.index)
        early = first[lane].notna() & (first[lane] < ours.fillna(np.inf))
        for name in first.index[early]:
            k = int(first.at[name, lane])
            r = w[(w.name == name) & (w.policy == lane) & (w.k == k)].iloc[0]
            rows.append(dict(name=name, family=r.family, lane=lane, k=k, x=r.x, y=r.y,
                             yaw_deg=r.yaw_deg, correct=bool(r.correct),
                             llr_grid=r.llr))  # fmt: skip
    return pd.DataFrame(rows)


def _recordings(tests: pd.DataFrame) -> dict:
    """The benchmark's recordings of the tests' runs, by name."""
    from mfcl_jax.bench.config import BenchmarkConfig, validate
    from mfcl_jax.bench.suite import nominal_recordings

    cfg = validate(BenchmarkConfig(families=sorted(set(tests.family)), faults=[],
                                   progress=False,
                                   cache=str(Path("~/.cache/mfcl_jax").expanduser())))  # fmt: skip
    names = set(tests.name)
    return {r.name: r for r in nominal_recordings(cfg) if r.name in names}


@partial(jax.jit, static_argnames="n_img")
def _search(ev, X, fields, n_img: int):
    from mfcl_jax.decision import rivals
    from mfcl_jax.decision.uniqueness import DEFAULT_UNIQUE as U

    rp = rivals.RivalParams(n_rivals=U.n_search, keep_ratio=0.0)
    return rivals.search(*ev, X, fields, n_img, rp)


@jax.jit
def _polish(found, pe, fields):
    from mfcl_jax.decision.uniqueness import DEFAULT_UNIQUE as U
    from mfcl_jax.frontend import path_llr

    return jax.vmap(lambda a: path_llr.refine(a, pe, fields, U.llr, U.polish))(found)


@jax.jit
def _edge(a, x_now, pe, fields):
    from mfcl_jax.decision.uniqueness import edge

    return edge(a, x_now, pe, fields)


def audit_one(rec, k: int, anchor, alpha: float, cache: dict) -> dict:
    """The branch and bound at window ``k`` of ``rec`` for the committed ``anchor (3,)``
    (``^B T_L``)."""
    import jax.numpy as jnp

    from experiments.audit import path_bound, path_certify
    from mfcl_jax import se2
    from mfcl_jax import windows as W
    from mfcl_jax.decision import rivals
    from mfcl_jax.frontend import path_llr
    from mfcl_jax.windows.arrays import evidence_sample

    w = W.cut(rec.seq, W.WindowParams(d_s=6.0))
    seg = np.asarray(w.segments)[np.asarray(w.bounds)[:k, 0]]
    first = int(np.flatnonzero(seg == seg[-1])[0])  # windows of the current segment only
    ev = [evidence_sample(w.points[i], w.origins[i]) for i in range(first, k)]
    X = np.asarray(w.X[first:k], np.float32)
    b = np.asarray(w.bounds)
    odo = np.asarray(w.odometry)[b[first, 0] : b[k - 1, 1] + 1]
    length = float(np.sum(np.hypot(*np.diff(odo[:, :2], axis=0).T)))
    ev_stack = tuple(np.stack([e[i] for e in ev]) for i in range(3))
    pe = path_llr.path_evidence(*ev_stack, X, length)
    key = id(rec.floorplan)
    if key not in cache:
        fields = jax.tree.map(jnp.asarray, rivals.rival_fields(rec.floorplan))
        cache[key] = (fields, path_bound.bound_fields(fields))
    fields, bf = cache[key]
    # the committed anchor ^B T_L (the benchmark's x, y, yaw), polished under this evidence
    a, L = path_llr.refine(jnp.asarray(anchor, jnp.float32), pe, fields)
    a, L = np.asarray(a, np.float64), float(L)
    margin = math.log(1.0 / alpha)
    r = path_certify.certify(pe, fields, bf, a, X[-1], L - margin)
    out = dict(outcome=r.outcome, why=r.why, L_star=L, margin=margin, cells=r.cells,
               levels=r.levels, seconds=round(r.seconds, 2), metres=length)  # fmt: skip
    # the lane's grid test on this evidence (its search's placements only, and the edge of
    # A*'s peak; the lane also fits the newest window's registrations and the probe's
    # aliases), fitted as the lane fits
    found, ok = _search(ev_stack, X, fields, rivals.image_size([rec.floorplan]))
    A, La = _polish(found, pe, fields)
    A, La = np.asarray(A, np.float64), np.asarray(La, np.float64)
    x_now = np.asarray(X[-1], np.float64)
    cn, an = se2.compose_host(A, x_now), se2.compose_host(a, x_now)
    far = (np.hypot(*(cn - an)[:, :2].T) > 1.0) | (
        np.abs(wrap_host(cn[:, 2] - an[2])) > math.radians(5.0)
    )
    # and the edge of A*'s own peak, which the lane also fits
    _, Le = _edge(jnp.asarray(a, jnp.float32), jnp.asarray(x_now, jnp.float32), pe, fields)
    out["llr_search"] = L - max(np.max(np.where(far & np.asarray(ok), La, -np.inf)), float(Le))
    if r.competitor is not None:
        # where the competitor places the robot now, against A*
        cn, an = se2.compose_host(r.competitor, x_now), se2.compose_host(a, x_now)
        dyaw = abs(math.degrees(math.remainder(cn[2] - an[2], 2 * math.pi)))
        out.update(llr_found=L - r.competitor_llr, comp_dxy=float(np.hypot(*(cn - an)[:2])),
                   comp_dyaw_deg=dyaw)  # fmt: skip
    return out


def summarise(table: pd.DataFrame) -> pd.DataFrame:
    """Tests per lane and finding; a competitor is ``near`` when it places the robot within
    2 m and 10 deg of ``A*`` (the same place, just past the 1 m / 5 deg line: the path's
    position along a corridor or a wall is that uncertain) and ``far`` otherwise (another
    place the grid search did not find)."""
    t = table.copy()
    near = (t.get("comp_dxy", np.nan) <= 2.0) & (t.get("comp_dyaw_deg", np.nan) <= 10.0)
    t["finding"] = np.where(t.outcome != "competitor", t.outcome,
                            np.where(near, "competitor near", "competitor far"))  # fmt: skip
    return (t.groupby(["lane", "finding"]).agg(tests=("name", "size"),
            commits_right=("correct", "sum"), median_metres=("metres", "median"),
            median_s=("seconds", "median"), max_s=("seconds", "max"))
            .round(1).reset_index())  # fmt: skip


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0
    out = Path(argv[0] if argv else "results/certificate_audit")
    lanes = argv[1].split(",") if len(argv) > 1 else ["ours_unique", "ours_unique_a2"]
    bad = [x for x in lanes if x not in LANES]
    if bad:
        raise SystemExit(f"audit.certificate: unknown lanes {bad}; known {list(LANES)}")
    windows = pd.read_csv("results/benchmark/windows.csv.gz", low_memory=False)
    tests = tests_of(windows, lanes)
    print(f"{len(tests)} tests: {tests.groupby('lane').size().to_dict()}", flush=True)
    t0 = time.perf_counter()
    recs = _recordings(tests)
    print(f"recordings: {len(recs)} in {time.perf_counter() - t0:.0f} s", flush=True)
    cache, rows = {}, []
    for i, t in enumerate(tests.itertuples(index=False)):
        res = audit_one(recs[t.name], t.k, [t.x, t.y, math.radians(t.yaw_deg)], LANES[t.lane],
                        cache)  # fmt: skip
        rows.append({**t._asdict(), **res})
        print(f"[{i + 1}/{len(tests)}] {t.name} {t.lane} k={t.k}: {res['outcome']} "
              f"{res['why']} ({res['seconds']} s)", flush=True)  # fmt: skip
    table = pd.DataFrame(rows)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "tests.csv", index=False)
    summary = summarise(table)
    (out / "summary.md").write_text(summary.to_markdown(index=False) + "\n")
    print(summary.to_markdown(index=False))
    if out.resolve() == Path("results/certificate_audit").resolve():
        from mfcl_jax.study.readme import update_docs

        names = update_docs("results")
        print(f"refreshed {', '.join(names) or 'no'} blocks in README.md and docs/")
    print(f"wrote {out}/tests.csv, {out}/summary.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
