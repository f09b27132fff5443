"""What weighing every storey costs a robot: the time per window of ``Localizer.run`` (the
front-end and the decision ``update`` of one window) on one storey, and on towers of ten.

Three plans, the same walk (a typical office floor of ``tower-<kind>-<seed>``, its scans
simulated once):

* ``one storey``: the typical floor alone (what ``--storey`` gives);
* ``typical x10``: a distinct ground floor under nine identical floors: congruent storeys
  share one place in the stacked plan (``floorplan.storeys``), so two places are searched;
* ``one_room x10``: ten floors identical but for one room each: ten places (the worst case:
  no two storeys congruent).

Each plan's first window compiles (reported apart); every later window is timed (wall).
Medians and 95th percentiles per plan and the ratio to one storey, all measured in this one
run. Writes ``results/bench_storeys.csv``, ``.md`` and ``.png`` (the table is pasted into
``docs/storeys.md``).
Usage: ``python benchmarks/storeys.py [--seed 0]``.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _timed(plan, seq):
    from mfcl_jax.robot.localizer import Localizer

    loc = Localizer(plan)
    out, t = [], time.perf_counter()
    for r in loc.run(seq):
        now = time.perf_counter()
        out.append((r.k, now - t, r.record(plan.offset)["state"]))
        t = now
    return out


def main(argv=None) -> int:
    from mfcl_jax.floorplan.storeys import stack_storeys
    from mfcl_jax.sim import SimParams
    from mfcl_jax.sim.families.tower import make_tower
    from mfcl_jax.sources.simulated import simulate

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    default = str(ROOT / "results" / "bench_storeys")
    ap.add_argument("--out", default=default)
    a = ap.parse_args(argv)

    typical = make_tower("typical", a.seed, 10)
    one_room = make_tower("one_room", a.seed, 10)
    scene = typical.scenes[1]
    walk = sorted(scene.trajectories)[0]
    rec = simulate(scene, [walk], [a.seed], SimParams())[0]
    plans = {
        "one storey": scene.floorplan,
        "typical x10": stack_storeys(typical.storeys, name=typical.name)[0],
        "one_room x10": stack_storeys(one_room.storeys, name=one_room.name)[0],
    }
    rows = []
    for name, plan in plans.items():
        tiles = 1 if plan.storeys is None else plan.storeys.n_tiles
        storeys = 1 if plan.storeys is None else len(plan.storeys.names)
        x0, y0, x1, y1 = plan.bounds
        times = _timed(plan, rec.seq)
        for k, dt, state in times:
            rows.append(dict(plan=name, storeys=storeys, places=tiles,
                             extent=f"{x1 - x0:.0f} x {y1 - y0:.0f} m", k=k, seconds=dt,
                             state=state))  # fmt: skip
        print(f"{name}: {len(times)} windows, first {times[0][1]:.1f} s", flush=True)
    df = pd.DataFrame(rows)
    pathlib.Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(a.out + ".csv", index=False)
    first = df[df.k == df.groupby("plan").k.transform("min")]
    rest = df[df.k != df.groupby("plan").k.transform("min")]
    g = rest.groupby("plan", sort=False)
    summ = pd.DataFrame({
        "storeys": g.storeys.first(), "places": g.places.first(), "extent": g.extent.first(),
        "first window s (compile)": first.set_index("plan").seconds,
        "median ms/window": g.seconds.median() * 1e3,
        "p95 ms/window": g.seconds.quantile(0.95) * 1e3,
    }).reindex(list(plans))  # fmt: skip
    base = summ.loc["one storey", "median ms/window"]
    summ["x one storey"] = summ["median ms/window"] / base
    text = summ.reset_index().to_markdown(index=False, floatfmt=".3g")
    pathlib.Path(a.out + ".md").write_text(
        f"Walk {walk} on {typical.name} storey L1 ({len(rec.seq.times)} scans), "
        f"{int(g.size().iloc[0])} timed windows per plan.\n\n{text}\n"
    )
    print(text)
    from mfcl_jax.study.readme import update_block

    if a.out == default:
        update_block(ROOT / "docs" / "storeys.md", "bench_storeys", a.out + ".md")
    fig, ax = plt.subplots(figsize=(6, 3.2))
    for name in plans:
        d = rest[rest.plan == name]
        ax.plot(d.k, d.seconds * 1e3, ".-", label=name)
    ax.set(xlabel="window k", ylabel="ms per window (wall)", yscale="log",
           title="per-window cost: one storey vs ten")  # fmt: skip
    ax.legend()
    fig.tight_layout()
    fig.savefig(a.out + ".png", dpi=120)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
