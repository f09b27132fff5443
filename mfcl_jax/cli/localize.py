"""``mfcl localize | evaluate | simulate``: the robot path, its scoring, and a dataset maker.

Thin: argument parsing; the runs (one input, many datasets, ``--follow``) are in
``mfcl_jax.cli.runs``, the work in ``mfcl_jax.robot.localizer``, ``localize_batch``, ``live``,
``score`` and ``sources``. Inputs, the odometry convention and the 3-D band:
``mfcl_jax.cli.inputs`` (flags: ``cli_flags``); what the status lines mean:
``mfcl_jax.robot.status``; ``--viz``: ``mfcl_jax.robot.viz``; ``evaluate --plot``:
``mfcl_jax.report.plots_run``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mfcl_jax.cli.flags import add_input_flags
from mfcl_jax.robot.status import help_text

__all__ = [
    "add_localize_commands",
    "cmd_localize",
    "cmd_evaluate",
    "cmd_simulate",
    "EXIT_BAD_INPUT",
    "EXIT_FALSE_COMMIT",
]

EXIT_BAD_INPUT = 2  # ``mfcl_jax.cli.main``: a bad input or an output that cannot be written
EXIT_FALSE_COMMIT = 3  # ``mfcl evaluate``: a COMMIT places the robot outside the tolerance

LOCALIZE_EPILOG = """\
decisions file (--out, JSON lines; one line per window):
  k is the window's index over the whole recording (it never starts again); segment is
  its odometry segment: 0, plus one after every odometry jump (a restart of the
  odometry). After a jump the decision layer starts over, and a line on stderr says
  where and why the run was split: the input odometry's step test (a step no robot
  makes) or the LiDAR odometry's jump test (a step the scans do not fit).

stopping: Ctrl-C (SIGINT) and SIGTERM (systemd, docker stop, timeout) stop any run the
  same way: what was decided so far is written, atomically (--out, --out-dir, --viz).

exit status:
  0    done; --follow: also when stopped by idle time, Ctrl-C or SIGTERM
  2    bad input or an output that cannot be written (several datasets: every bad one
       is named and none decided; with --keep-going the others are decided and
       written, and the exit status is still 2)
  130  one dataset or several: stopped by Ctrl-C (the windows decided so far written)
  143  the same, stopped by SIGTERM"""

EVALUATE_EPILOG = f"""\
judged by: a COMMIT is correct when the robot's pose it gives (its anchor composed with
  odometry.tum at the decision's time) is within 1 m and 5 deg of groundtruth.tum at that
  time (CORRECT_XY, CORRECT_YAW_DEG in mfcl_jax.score.summary; every evaluation prints
  them). DEFER and AMBIGUOUS windows place nothing and are not judged.
  Lines are taken in time order; each odometry segment (a new one after every odometry
  jump) is reported on its own, as the decision layer starts over there.

exit status:
  0    no COMMIT is false (or --exit-zero)
  2    bad input
  {EXIT_FALSE_COMMIT}    a false commit: some COMMIT line places the robot outside the tolerance"""


def add_localize_commands(subparsers) -> None:
    """Adds ``localize``, ``evaluate`` and ``simulate`` to an argparse sub-parser set."""
    lo = subparsers.add_parser(
        "localize",
        help="register submap windows to a floor plan and decide per window",
        description="Register submap windows to a floor plan and decide, window by window, "
        "whether the robot is localized (COMMIT), in a symmetric place (AMBIGUOUS) or not yet "
        "(DEFER). Status lines go to stdout, decisions to a JSON-lines file.",
        epilog=help_text() + "\n\n" + LOCALIZE_EPILOG,
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
        "--viz",
        type=Path,
        metavar="FILE.mcap",
        help="also write the run for a person to look at: an MCAP file that Foxglove opens "
        "(the plan, the scans placed at the committed anchor, the anchored path, each "
        "window's state and alternatives, on a timeline; written atomically at the end, as "
        "the decisions are; one dataset only; see mfcl_jax.robot.viz)",
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
    lo.add_argument(
        "--keep-going",
        action="store_true",
        help="several datasets: decide the good ones when some cannot be read (they are "
        "named on stderr; exit status 2); default: name every bad one and decide none",
    )
    lo.add_argument("--quiet", action="store_true", help="no per-window status lines")
    add_progress_flag(lo)
    lo.set_defaults(func=cmd_localize)

    ev = subparsers.add_parser(
        "evaluate",
        help="score a decisions log against groundtruth.tum",
        description="Score a decisions log against the dataset's groundtruth.tum: the first\n"
        "commit, every commit and the final state, over the run and per odometry segment,\n"
        "in time order.",
        epilog=EVALUATE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ev.add_argument("dataset", type=Path, help="dataset folder with groundtruth.tum")
    ev.add_argument("--decisions", type=Path, required=True, help="decisions JSON lines")
    ev.add_argument("--windows", action="store_true", help="also print every window")
    ev.add_argument(
        "--exit-zero",
        action="store_true",
        help=f"exit 0 even when a false commit is found (default: exit {EXIT_FALSE_COMMIT})",
    )
    ev.add_argument(
        "--plot",
        type=Path,
        metavar="FILE.png",
        help="also draw the plan, the true path, the odometry placed by the first commit "
        "(green: correct, red: false) and the commits (.png, .pdf or .svg; written atomically)",
    )
    ev.add_argument(
        "--floorplan",
        type=Path,
        help="--plot: the floor plan to draw (default: the dataset's floorplan.*)",
    )
    ev.add_argument("--storey", help="--plot: IFC storey name or elevation")
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
    from mfcl_jax.cli.runs import localize
    from mfcl_jax.robot.progress import Progress

    return localize(args, Progress(True if args.progress else None))


def cmd_evaluate(args) -> int:
    """``mfcl evaluate``: the report (tolerances, the run, its segments, the verdict); exit
    ``EXIT_FALSE_COMMIT`` when some COMMIT is false (unless ``--exit-zero``)."""
    import pandas as pd

    from mfcl_jax.io import DataError, read_decisions, read_tum
    from mfcl_jax.score import CORRECT_XY, CORRECT_YAW_DEG, format_table, score_rows, summarize
    from mfcl_jax.score.decisions import decisions_frame, segment_summaries

    folder = args.dataset
    if not folder.is_dir():
        raise DataError(f"{folder}: dataset folder not found")
    gt_path = folder / "groundtruth.tum"
    if not gt_path.is_file():
        raise DataError(f"{gt_path}: no ground truth in this dataset; evaluate needs it")
    plan = _check_plot(args) if args.plot is not None else None
    decisions = read_decisions(args.decisions)
    ot, odo = read_tum(folder / "odometry.tum")
    gt_t, gt = read_tum(gt_path)
    frame = decisions_frame(decisions)  # in time order, with segments
    scored = score_rows(frame, ot, odo, gt_t, gt, where=str(args.decisions))
    print(f"judged by: a COMMIT is correct within {CORRECT_XY:.2f} m and {CORRECT_YAW_DEG:.1f} "
          f"deg of {gt_path.name} at the decision's time (the robot's pose it gives: its "
          f"anchor composed with odometry.tum); DEFER and AMBIGUOUS windows place nothing "
          "and are not judged")  # fmt: skip
    if decisions and not any("segment" in d for d in decisions):
        print(f"note: {args.decisions} has no segment field (written before segments were "
              "reported): a new segment is taken to start wherever k does not grow")  # fmt: skip
    s = summarize(scored)
    n_seg = int(scored["segment"].nunique()) if len(scored) else 0
    print(format_table(pd.DataFrame([dict(windows=s["windows"], segments=n_seg) | _row(s)])))
    if n_seg > 1:
        print("\nper odometry segment (the decision layer starts over after each jump):")
        rows = []
        for g in segment_summaries(scored):
            rows.append(
                {"segment": g["segment"], "windows": g["windows"],
                 "k": f"{g['k_first']}-{g['k_last']}",
                 "t [s]": f"{g['t_first']:.2f}-{g['t_last']:.2f}"} | _row(g)
            )  # fmt: skip
        print(format_table(pd.DataFrame(rows)))
    if args.windows and len(scored):
        print()
        print(format_table(_windows(scored), missingval="-"))
    if plan is not None:
        from mfcl_jax.floorplan.load import load_floorplan
        from mfcl_jax.report.plots_run import plot_run

        fp = load_floorplan(plan, storey=args.storey)
        print(f"figure: {plot_run(args.plot, fp, gt, odo, scored, folder.name)}")
    com = scored[scored["state"] == "COMMIT"] if len(scored) else scored
    wrong = com[~com["correct"].astype(bool)] if len(com) else com
    if not len(com):
        print("verdict: no commit, nothing to judge")
        return 0
    if not len(wrong):
        print(f"verdict: no false commit ({len(com)}/{len(com)} COMMIT windows correct)")
        return 0
    w = wrong.iloc[0]
    code = 0 if args.exit_zero else EXIT_FALSE_COMMIT
    print(f"verdict: FALSE COMMIT: {len(wrong)} of {len(com)} COMMIT windows are wrong, the "
          f"first at k={int(w['k'])} (t={w['t']:.2f} s, segment {int(w['segment'])}): "
          f"{w['err_xy']:.2f} m and {w['err_yaw_deg']:.1f} deg off; exit status {code}"
          + (" (--exit-zero)" if args.exit_zero else ""))  # fmt: skip
    return code


def _row(s: dict) -> dict:
    """The table columns of a ``summarize`` result."""
    has = s["first_commit_k"] is not None
    return {
        "first commit k": s["first_commit_k"] if has else "-",
        "t": s["first_commit_t"] if has else "-",
        "err xy [m]": s["err_xy"] if has else "-",
        "err yaw [deg]": s["err_yaw_deg"] if has else "-",
        "verdict": "-" if s["correct"] is None else ("correct" if s["correct"] else "FALSE"),
        "commits correct": f"{s['commits_correct']}/{s['commits']}",
        "final state": s["final_state"] or "-",
    }


def _windows(scored):
    """Every window, for ``--windows``: errors and correctness only where a COMMIT placed
    the robot (``-`` elsewhere)."""
    cols = ["k", "segment", "t", "state", "symmetry", "B1", "B2", "margin", "err_xy",
            "err_yaw_deg", "correct"]  # fmt: skip
    df = scored[cols].astype(object)
    commit = (scored["state"] == "COMMIT").to_numpy()
    for c in ("err_xy", "err_yaw_deg"):
        df[c] = [float(v) if m else None for v, m in zip(scored[c], commit, strict=True)]
    df["correct"] = [("yes" if v else "NO") if m else None
                     for v, m in zip(scored["correct"], commit, strict=True)]  # fmt: skip
    df["symmetry"] = [v if isinstance(v, str) else None for v in scored["symmetry"]]
    df = df.astype(object)
    return df.where(df.notna(), None)


def _check_plot(args) -> Path:
    """``evaluate --plot``: the floor plan to draw, and the figure's path checked (its type,
    and that it is none of the inputs and can be written), before any work."""
    from mfcl_jax.floorplan.load import floorplan_files
    from mfcl_jax.io import DataError, check_output
    from mfcl_jax.report.plots_run import FORMATS
    from mfcl_jax.sources.dataset import FLOORPLAN_NAMES

    out, folder = args.plot, args.dataset
    if out.suffix.lower() not in FORMATS:
        raise DataError(f"{out}: --plot writes a figure; give a name ending in one of {FORMATS}")
    plan = args.floorplan
    if plan is None:
        plans = [folder / n for n in FLOORPLAN_NAMES if (folder / n).is_file()]
        if len(plans) != 1:
            found = [p.name for p in plans] or "none"
            raise DataError(
                f"{folder}: --plot draws the floor plan: the dataset needs exactly one of "
                f"{FLOORPLAN_NAMES} (found {found}), or give --floorplan F"
            )
        plan = plans[0]
    elif not plan.is_file():
        raise DataError(f"{plan}: --floorplan not found")
    inputs = [args.decisions, folder / "odometry.tum", folder / "groundtruth.tum"]
    check_output(out, inputs=inputs + floorplan_files(plan))
    return plan


def cmd_simulate(args) -> int:
    from mfcl_jax.floorplan.load import floorplan_files, load_floorplan
    from mfcl_jax.io import DataError, check_output
    from mfcl_jax.robot.progress import COMPILING, Progress

    progress = Progress(True if args.progress else None)
    if args.out.exists() and not args.overwrite:
        raise DataError(f"{args.out}: already exists (pass --overwrite to replace it)")
    inputs = [args.trajectory, *floorplan_files(args.floorplan)]
    check_output(args.out, inputs=inputs, folder=True)
    with progress.stage("starting (loading JAX)"):
        from mfcl_jax.robot.compile_cache import enable_cache
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
