"""``mfcl localize | evaluate | simulate``: the robot path, its scoring, and a dataset maker.

Thin: argument parsing and printing; the work is in ``mfcl_jax.localizer``, ``mfcl_jax.score``
and ``mfcl_jax.sources``.
Inputs, the odometry convention and plan-frame anchors: ``mfcl_jax.cli_inputs``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from mfcl_jax.cli_floorplan import add_rosmap_flags
from mfcl_jax.cli_inputs import lidar_offset_arg

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
        help="dataset folder (floorplan.*, odometry.tum, scans/); omit with --bag/--carmen",
    )
    lo.add_argument(
        "--floorplan", type=Path, help="floor plan (.ifc/.geojson/.yaml); overrides the dataset's"
    )
    lo.add_argument("--bag", type=Path, help="ROS1 .bag or ROS2 bag folder instead of a dataset")
    lo.add_argument("--scan-topic", default="/scan", help="LaserScan/PointCloud2 topic (/scan)")
    lo.add_argument("--odom-topic", default="/odom", help="nav_msgs/Odometry topic (/odom)")
    lo.add_argument(
        "--carmen", type=Path, help="CARMEN log (.log/.log.gz; its odometry columns) instead"
    )
    lo.add_argument(
        "--lidar-offset",
        type=lidar_offset_arg,
        metavar="X,Y,YAW_DEG",
        help="LiDAR pose in the robot base frame (bags and CARMEN logs; m, m, deg)",
    )
    lo.add_argument(
        "--tf-static",
        action="store_true",
        help="bags: read the LiDAR mounting from /tf_static (chain --base-frame -> scan frame)",
    )
    lo.add_argument("--base-frame", default="base_link", help="--tf-static parent (base_link)")
    add_rosmap_flags(lo)
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


def cmd_localize(args) -> int:
    from mfcl_jax.cli_inputs import input_paths, load_input, plan_frame_decision
    from mfcl_jax.io import DataError, check_output

    if not args.d_s > 0:
        raise DataError(f"localize: --d-s must be > 0, got {args.d_s}")
    if args.out.is_dir():
        raise DataError(f"{args.out}: --out is a folder, expected a file name")
    check_output(args.out, inputs=input_paths(args))
    from tqdm import tqdm

    from mfcl_jax.io import write_decisions
    from mfcl_jax.localizer import LocalizeParams, Localizer

    fp, seq, notes = load_input(args)
    for note in notes:
        print(note, file=sys.stderr)
    loc = Localizer(fp, LocalizeParams().with_d_s(args.d_s))
    n = loc.n_windows(seq)
    print(
        f"{seq.source}: {len(seq)} scans, {n} windows of {args.d_s:g} m; floor plan {fp.name}",
        file=sys.stderr,
    )
    offset = [float(v) for v in fp.offset]
    if any(offset):
        print(
            f"{fp.name}: localized in a local frame (plan = local + ({offset[0]:.3f}, "
            f"{offset[1]:.3f})); status lines show local anchors, {args.out} plan-frame ones",
            file=sys.stderr,
        )
    if n == 0:
        print("no complete window: the odometry travels less than d_s", file=sys.stderr)
    decisions, first = [], None
    try:
        with tqdm(total=n, file=sys.stderr, unit="win", dynamic_ncols=True) as bar:
            for r in loc.run(seq):
                decisions.append(plan_frame_decision(json.loads(r.decision.to_json()), offset))
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
    from mfcl_jax.floorplan.load import floorplan_files, load_floorplan
    from mfcl_jax.io import DataError, check_output

    if args.out.exists() and not args.overwrite:
        raise DataError(f"{args.out}: already exists (pass --overwrite to replace it)")
    inputs = [args.trajectory, *floorplan_files(args.floorplan)]
    check_output(args.out, inputs=inputs, folder=True)
    from mfcl_jax.sources.simulated import simulate_dataset
    from mfcl_jax.sources.walks import read_waypoints

    wp = read_waypoints(args.trajectory)
    fp = load_floorplan(args.floorplan, storey=args.storey)
    out = simulate_dataset(
        fp, wp, args.out, seed=args.seed, overwrite=args.overwrite, where=str(args.trajectory)
    )
    from mfcl_jax.io import read_tum

    t, _ = read_tum(out / "odometry.tum")
    print(f"{out}: {len(t)} scans over {t[-1] - t[0]:.1f} s in {fp.name} (seed {args.seed})")
    return 0
