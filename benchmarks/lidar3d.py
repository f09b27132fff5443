"""3-D LiDAR input: does a sliced 3-D cloud commit as its 2-D twin does?

For each walk (``three_rooms`` T1 and T2 with their furniture, Office_A ``open_office_to_113``
on the IFC walls) one simulation gives true poses, drifting odometry, Livox Mid-360-like clouds
(0.5 m above the floor, ceiling 2.8 m / 3.0 m) and the planar ring at the same poses. The
localizer (default ``LocalizeParams``) then runs on three scan sequences that share the
odometry:

* ``2d``: the planar ring (what ``mfcl`` consumed so far);
* ``3d_band``: the clouds through ``cloud3d.slice_clouds`` with the default ``BandParams``;
* ``3d_raw``: the clouds projected onto x, y without a band (floor, ceiling and all).

``T1_tilted`` repeats T1 with the mount pitched 3 deg and rolled 1 deg (band input only).

Ground truth only scores. Writes ``results/lidar3d.csv`` and ``results/lidar3d.md``.

Run: ``nice python -m benchmarks.lidar3d [--no-office] [--out results/lidar3d]``
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from mfcl_jax.io.atomic import atomic_write_text
from mfcl_jax.robot.localizer import Localizer
from mfcl_jax.score import format_table, score_decisions, summarize
from mfcl_jax.sim.lidar3d import livox_mid360
from mfcl_jax.sim.scenes import three_rooms
from mfcl_jax.sources.cloud3d import BandParams, slice_clouds
from mfcl_jax.sources.sequence import ScanSequence
from mfcl_jax.sources.walk3d import scene_walk3d, walk3d

OFFICE_IFC = Path("/work/shared/data/ifc/Office_A_20110811.ifc")
SENSOR = livox_mid360(height=0.5)
# The same sensor on a mount pitched 3 deg and rolled 1 deg, sliced without being told.
TILTED = livox_mid360(height=0.5, pitch_deg=3.0, roll_deg=1.0)
ALL, BANDED = ("2d", "3d_band", "3d_raw"), ("3d_band",)
BAND = BandParams()


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _walks(office: bool):
    """``(building, walk label, floor plan, sensor, Walk3D, inputs)`` per case."""
    scene = three_rooms()
    cases = [
        ("T1", "T1", SENSOR, ALL),
        ("T2", "T2", SENSOR, ALL),
        ("T1", "T1_tilted", TILTED, BANDED),
    ]
    for name, label, sensor, kinds in cases:
        t0 = time.perf_counter()
        w = scene_walk3d(scene, name, sensor, h_ceil=2.8)
        _log(f"three_rooms/{label}: {len(w.t)} scans simulated in {time.perf_counter() - t0:.1f} s")
        yield "three_rooms", label, scene.floorplan, sensor, w, kinds
    if office and OFFICE_IFC.exists():
        from mfcl_jax.floorplan.load import load_floorplan
        from mfcl_jax.sources.walks import route
        from mfcl_jax.study.real_walks import OFFICE

        fp = load_floorplan(OFFICE_IFC, storey=OFFICE["storey"])
        name = "open_office_to_113"
        rooms, _, _ = OFFICE["walks"][name]
        t0 = time.perf_counter()
        # The tag of experiments.real: the same odometry and 2-D scans as its Office_A case.
        w = walk3d(fp, route(fp, rooms), SENSOR, h_ceil=3.0, tag=name)
        _log(f"Office_A/{name}: {len(w.t)} scans simulated in {time.perf_counter() - t0:.1f} s")
        yield "Office_A", name, fp, SENSOR, w, ALL


def _inputs(w, sensor):
    """The three scan sequences of one walk, with notes."""
    t0 = time.perf_counter()
    band, infos, detected = slice_clouds(w.clouds, BAND, where="walk")
    dt = time.perf_counter() - t0
    raw = [c[np.all(np.isfinite(c), 1), :2].astype(np.float64) for c in w.clouds]
    found = [f for f in detected if f is not None]
    h = np.array([f.height for f in found])
    tilt = np.array([f.tilt_deg for f in found])
    used = infos[0].floor
    tilt_true = np.hypot(sensor.roll_deg, sensor.pitch_deg)
    note = (
        f"floor used {used.height:.3f} m below the sensor, tilt {used.tilt_deg:.2f} deg (true "
        f"{sensor.height} m, {tilt_true:.2f} deg); per-cloud detections: "
        f"{len(found)}/{len(detected)}, height median {np.median(h):.3f} (5-95 %: "
        f"{np.percentile(h, 5):.3f}-{np.percentile(h, 95):.3f}), tilt median "
        f"{np.median(tilt):.2f} deg; {dt / len(infos) * 1e3:.0f} ms/cloud"
    )
    return {"2d": list(w.scans2d), "3d_band": band, "3d_raw": raw}, note


def _localize(loc: Localizer, fp, w, scans, case: dict) -> dict:
    seq = ScanSequence(w.t, scans, w.odom, f"{case['building']}/{case['walk']}/{case['input']}")
    t0 = time.perf_counter()
    decs = [r.record() for r in loc.run(seq)]  # anchors against the input odometry
    dt = time.perf_counter() - t0
    s = summarize(score_decisions(decs, w.t, w.odom, w.t, w.true, fp, where=seq.source))
    states = "".join({"COMMIT": "C", "DEFER": "d", "AMBIGUOUS": "a"}[d["state"]] for d in decs)
    first = s["first_commit_k"]
    return dict(
        **case,
        pts_per_scan=int(np.median([len(x) for x in scans])),
        windows=s["windows"],
        first_commit_k=math.nan if first is None else first,
        final_state=s["final_state"],
        err_xy_m=s["err_xy"],
        err_yaw_deg=s["err_yaw_deg"],
        verdict="-" if s["correct"] is None else "correct" if s["correct"] else "FALSE",
        commits_correct=f"{s['commits_correct']}/{s['commits']}",
        states=states,
        seconds=round(dt, 1),
    )


def run(out: Path, office: bool = True) -> pd.DataFrame:
    rows, notes = [], []
    locs: dict[str, Localizer] = {}
    for building, walk, fp, sensor, w, kinds in _walks(office):
        loc = locs.setdefault(building, Localizer(fp))
        inputs, note = _inputs(w, sensor)
        notes.append(f"- {building}/{walk}: {note}")
        for kind in kinds:
            scans = inputs[kind]
            case = dict(building=building, walk=walk, input=kind)
            rows.append(_localize(loc, fp, w, scans, case))
            r = rows[-1]
            _log(f"  {kind:8s} {r['states']}  first commit k={r['first_commit_k']}")
    df = pd.DataFrame(rows)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out.with_suffix(".csv"), df.to_csv(index=False))
    cols = [c for c in df.columns if c not in ("states", "seconds")]
    md = [
        "# 3-D LiDAR input vs its 2-D twin",
        "",
        "Generated by `python -m benchmarks.lidar3d`. One simulated walk per row group: the",
        f"same true poses and odometry, three inputs. Sensor: Livox Mid-360-like, "
        f"{len(SENSOR.elevation_deg)} rings x {SENSOR.n_azimuth} azimuths "
        f"(-7..52 deg, non-repetitive shift), {SENSOR.height} m above the floor; ceiling "
        "2.8 m (three_rooms, with furniture of 0.75-2.0 m and full-height shelves and "
        "partitions) or 3.0 m (Office_A, IFC walls only). `2d`: the planar ring at the "
        "sensor height; `3d_band`: `cloud3d.slice_clouds` with the default band "
        f"({BAND.describe()}); `3d_raw`: every 3-D point projected onto x, y. Default "
        "`LocalizeParams` (d_s = 6 m). `T1_tilted`: T1 with the sensor's mount pitched 3 deg "
        "and rolled 1 deg, sliced with no mount given (the floor fit levels it). Errors are "
        "the first commit's; correct means < 1 m and < 5 deg.",
        "",
        format_table(df[cols]),
        "",
        "States per window (d DEFER, a AMBIGUOUS, C COMMIT):",
        "",
    ]
    md += [f"- {r.building}/{r.walk} `{r.input}`: `{r.states}`" for r in df.itertuples()]
    md += ["", "Floor detection of the band slicer:", "", *notes, ""]
    atomic_write_text(out.with_suffix(".md"), "\n".join(md))
    return df


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="3-D LiDAR input vs its 2-D twin")
    ap.add_argument("--out", default="results/lidar3d", help="output stem (.csv and .md)")
    ap.add_argument("--no-office", action="store_true", help="skip the Office_A IFC walk")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    df = run(Path(a.out), office=not a.no_office)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(df.drop(columns=["states"]).to_string(index=False))
    _log(f"done in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
