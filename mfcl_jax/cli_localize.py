"""``mfcl localize | evaluate | simulate``: the robot path, its scoring, and a dataset maker.

Thin: argument parsing and printing; the work is in ``mfcl_jax.localizer``, ``mfcl_jax.score``
and ``mfcl_jax.sources``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

__all__ = ["add_localize_commands", "cmd_localize", "cmd_evaluate", "cmd_simulate"]


def add_localize_commands(subparsers) -> None:
    """Adds ``localize``, ``evaluate`` and ``simulate`` to an argparse sub-parser set."""
    lo = subparsers.add_parser(
        "localize", help="register submap windows to a floor plan and decide per window"
    )
    lo.add_argument(
        "dataset",
        type=Path,
        nargs="?",
        help="dataset folder (floorplan.*, odometry.tum, scans/); omit with --bag",
    )
    lo.add_argument(
        "--floorplan", type=Path, help="floor plan (.ifc/.geojson/.yaml); overrides the dataset's"
    )
    lo.add_argument("--bag", type=Path, help="ROS1 .bag or ROS2 bag folder instead of a dataset")
    lo.add_argument("--scan-topic", default="/scan", help="LaserScan/PointCloud2 topic (/scan)")
    lo.add_argument("--odom-topic", default="/odom", help="nav_msgs/Odometry topic (/odom)")
    lo.add_argument("--d-s", type=float, default=6.0, help="window length in metres (6)")
    lo.add_argument("--storey", help="IFC storey name or elevation")
    lo.add_argument(
        "--out",
        type=Path,
        default=Path("decisions.jsonl"),
        help="decisions JSON lines (written atomically; default decisions.jsonl)",
    )
    lo.add_argument("--quiet", action="store_true", help="no per-window status lines")
    lo.set_defaults(func=cmd_localize)

    ev = subparsers.add_parser("evaluate", help="score a decisions log against groundtruth.tum")
    ev.add_argument("dataset", type=Path, help="dataset folder with groundtruth.tum")
    ev.add_argument("--decisions", type=Path, required=True, help="decisions JSON lines")
    ev.add_argument("--windows", action="store_true", help="also print every window")
    ev.set_defaults(func=cmd_evaluate)

    si = subparsers.add_parser(
        "simulate", help="write a dataset folder by simulating a LiDAR walk through a floor plan"
    )
    si.add_argument("--floorplan", type=Path, required=True, help=".ifc, .geojson or .yaml")
    si.add_argument("--trajectory", type=Path, required=True, help="waypoints CSV: x,y per line")
    si.add_argument("--out", type=Path, required=True, help="dataset folder to create")
    si.add_argument("--seed", type=int, default=0, help="noise and drift seed (0)")
    si.add_argument("--storey", help="IFC storey name or elevation")
    si.add_argument("--overwrite", action="store_true", help="replace an existing folder")
    si.set_defaults(func=cmd_simulate)


def _load_input(args):
    """(floorplan, ScanSequence) from a dataset folder or a bag."""
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.io import DataError, load_dataset, read_bag
    from mfcl_jax.sources.sequence import from_bag, from_dataset

    if args.bag is None and args.dataset is None:
        raise DataError("localize: give a DATASET folder or --bag B (with --floorplan F)")
    if args.bag is not None and args.dataset is not None:
        raise DataError(f"localize: give either DATASET ({args.dataset}) or --bag ({args.bag})")
    fp = None
    if args.floorplan is not None:
        fp = load_floorplan(args.floorplan, storey=args.storey)
    if args.bag is not None:
        if fp is None:
            raise DataError(f"{args.bag}: a bag has no floor plan; pass --floorplan F")
        bag = read_bag(args.bag, args.scan_topic, args.odom_topic)
        return fp, from_bag(bag, str(args.bag))
    ds = load_dataset(args.dataset, storey=args.storey, floorplan=fp)
    return ds.floorplan, from_dataset(ds)


def cmd_localize(args) -> int:
    from tqdm import tqdm

    from mfcl_jax.io import DataError, write_decisions
    from mfcl_jax.localizer import LocalizeParams, Localizer

    if not args.d_s > 0:
        raise DataError(f"localize: --d-s must be > 0, got {args.d_s}")
    if args.out.is_dir():
        raise DataError(f"{args.out}: --out is a folder, expected a file name")
    fp, seq = _load_input(args)
    loc = Localizer(fp, LocalizeParams().with_d_s(args.d_s))
    n = loc.n_windows(seq)
    print(
        f"{seq.source}: {len(seq)} scans, {n} windows of {args.d_s:g} m; floor plan {fp.name}",
        file=sys.stderr,
    )
    if n == 0:
        print("no complete window: the odometry travels less than d_s", file=sys.stderr)
    decisions, first = [], None
    try:
        with tqdm(total=n, file=sys.stderr, unit="win", dynamic_ncols=True) as bar:
            for r in loc.run(seq):
                decisions.append(json.loads(r.decision.to_json()))
                if first is None and r.decision.state == "COMMIT":
                    first = r.decision.k
                if not args.quiet:
                    bar.write(r.status(), file=sys.stdout)
                bar.update(1)
    except KeyboardInterrupt:
        print(
            f"mfcl: interrupted after {len(decisions)} windows; {args.out} not written",
            file=sys.stderr,
        )
        return 130
    write_decisions(args.out, decisions)
    last = decisions[-1]["state"] if decisions else "none"
    verdict = f"first COMMIT at window {first}" if first else "no commit"
    print(f"{len(decisions)} windows, {verdict}, final state {last}; decisions: {args.out}")
    return 0


def cmd_evaluate(args) -> int:
    import pandas as pd

    from mfcl_jax.io import DataError, read_decisions, read_tum
    from mfcl_jax.score import format_table, score_decisions, summarize

    folder = args.dataset
    if not folder.is_dir():
        raise DataError(f"{folder}: dataset folder not found")
    gt_path = folder / "groundtruth.tum"
    if not gt_path.is_file():
        raise DataError(f"{gt_path}: no ground truth in this dataset; evaluate needs it")
    decisions = read_decisions(args.decisions)
    ot, odo = read_tum(folder / "odometry.tum")
    gt_t, gt = read_tum(gt_path)
    scored = score_decisions(decisions, ot, odo, gt_t, gt, where=str(args.decisions))
    s = summarize(scored)
    row = pd.DataFrame(
        [
            {
                "windows": s["windows"],
                "first commit k": s["first_commit_k"] if s["first_commit_k"] else "-",
                "t": s["first_commit_t"] if s["first_commit_t"] is not None else "-",
                "err xy [m]": s["err_xy"],
                "err yaw [deg]": s["err_yaw_deg"],
                "verdict": "-"
                if s["correct"] is None
                else ("correct" if s["correct"] else "FALSE"),
                "commits correct": f"{s['commits_correct']}/{s['commits']}",
                "final state": s["final_state"] or "-",
            }
        ]
    )
    print(format_table(row))
    if args.windows and len(scored):
        cols = [
            "k",
            "t",
            "state",
            "symmetry",
            "B1",
            "B2",
            "margin",
            "err_xy",
            "err_yaw_deg",
            "correct",
        ]
        print()
        print(format_table(scored[cols]))
    return 0


def cmd_simulate(args) -> int:
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.io import DataError
    from mfcl_jax.sources.simulated import simulate_dataset
    from mfcl_jax.sources.walks import read_waypoints

    if args.out.exists() and not args.overwrite:
        raise DataError(f"{args.out}: already exists (pass --overwrite to replace it)")
    wp = read_waypoints(args.trajectory)
    fp = load_floorplan(args.floorplan, storey=args.storey)
    out = simulate_dataset(
        fp, wp, args.out, seed=args.seed, overwrite=args.overwrite, where=str(args.trajectory)
    )
    from mfcl_jax.io import read_tum

    t, _ = read_tum(out / "odometry.tum")
    print(f"{out}: {len(t)} scans over {t[-1] - t[0]:.1f} s in {fp.name} (seed {args.seed})")
    return 0
