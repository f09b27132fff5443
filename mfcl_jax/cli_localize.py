"""``mfcl localize | evaluate | simulate``: the robot path, its scoring, and a dataset maker.

Thin: argument parsing; the runs (one input, many datasets, ``--follow``) are in
``mfcl_jax.cli_runs``, the work in ``mfcl_jax.localizer``, ``localize_batch``, ``live``,
``score`` and ``sources``. Inputs, the odometry convention and the 3-D band:
``mfcl_jax.cli_inputs`` (flags: ``cli_flags``); what the status lines mean: ``mfcl_jax.status``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mfcl_jax.cli_flags import add_input_flags
from mfcl_jax.status import help_text

__all__ = ["add_localize_commands", "cmd_localize", "cmd_evaluate", "cmd_simulate"]


def add_localize_commands(subparsers) -> None:
    """Adds ``localize``, ``evaluate`` and ``simulate`` to an argparse sub-parser set."""
    lo = subparsers.add_parser(
        "localize",
        help="register submap windows to a floor plan and decide per window",
        description="Register submap windows to a floor plan and decide, window by window, "
        "whether the robot is localized (COMMIT), in a symmetric place (AMBIGUOUS) or not yet "
        "(DEFER). Status lines go to stdout, decisions to a JSON-lines file.",
        epilog=help_text(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_input_flags(lo)
    lo.add_argument("--d-s", type=float, default=6.0, help="window length in metres (6)")
    lo.add_argument(
        "--no-scan-match",
        action="store_true",
        help="build submaps on the input odometry as it is (default: keyframe poses refined by "
        "LiDAR scan matching first, which removes wheel-odometry drift; an LIO's odometry "
        "needs no refinement)",
    )
    lo.add_argument(
        "--out",
        type=Path,
        help="decisions JSON lines (written atomically; default decisions.jsonl; with "
        "--follow: written at the end, only when given)",
    )
    lo.add_argument(
        "--out-dir",
        type=Path,
        help="one decisions file per dataset, <dataset name>.jsonl (several datasets)",
    )
    lo.add_argument(
        "--follow",
        type=Path,
        metavar="DIR",
        help="live: watch a dataset folder being written; decide as windows complete, stream "
        "the decisions as JSON lines on stdout (status on stderr); stop on Ctrl-C or idle",
    )
    lo.add_argument(
        "--idle-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="--follow: stop after S seconds without new data (10)",
    )
    lo.add_argument("--quiet", action="store_true", help="no per-window status lines")
    add_progress_flag(lo)
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
    add_progress_flag(si)
    si.set_defaults(func=cmd_simulate)


def add_progress_flag(parser) -> None:
    parser.add_argument(
        "--progress",
        action="store_true",
        help="progress messages on stderr even when it is not a terminal (default: only then)",
    )


def cmd_localize(args) -> int:
    from mfcl_jax.cli_runs import localize
    from mfcl_jax.progress import Progress

    return localize(args, Progress(True if args.progress else None))


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
    from mfcl_jax.progress import COMPILING, Progress

    progress = Progress(True if args.progress else None)
    if args.out.exists() and not args.overwrite:
        raise DataError(f"{args.out}: already exists (pass --overwrite to replace it)")
    inputs = [args.trajectory, *floorplan_files(args.floorplan)]
    check_output(args.out, inputs=inputs, folder=True)
    with progress.stage("starting (loading JAX)"):
        from mfcl_jax.compile_cache import enable_cache
        from mfcl_jax.sources.simulated import simulate_dataset
        from mfcl_jax.sources.walks import read_waypoints

        enable_cache()
    wp = read_waypoints(args.trajectory)
    with progress.stage(f"loading {args.floorplan}"):
        fp = load_floorplan(args.floorplan, storey=args.storey)
    with progress.stage(f"simulating the walk and writing {args.out} (ray caster: {COMPILING})"):
        out = simulate_dataset(
            fp, wp, args.out, seed=args.seed, overwrite=args.overwrite, where=str(args.trajectory)
        )
    from mfcl_jax.io import read_tum

    t, _ = read_tum(out / "odometry.tum")
    print(f"{out}: {len(t)} scans over {t[-1] - t[0]:.1f} s in {fp.name} (seed {args.seed})")
    return 0
