"""``mfcl evaluate``: a decisions file scored against the dataset's ground truth, in time
order and per odometry segment, with the tolerances it judges by (``mfcl_jax.score``);
``--plot`` draws the run on the plan (``mfcl_jax.report.plots_run``)."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["add_evaluate_command", "cmd_evaluate", "EXIT_FALSE_COMMIT"]

EXIT_FALSE_COMMIT = 3  # a COMMIT places the robot outside the tolerance

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


def add_evaluate_command(subparsers) -> None:
    """Adds ``evaluate`` to an argparse sub-parser set."""
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
    ev.add_argument(
        "--storey",
        help="the storey the recording was made on (a plan of several "
        "storeys): a COMMIT that names another storey is false; --plot draws it",
    )
    ev.set_defaults(func=cmd_evaluate)


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
    named = [d.get("storey") for d in decisions if d["state"] == "COMMIT"]
    if any(n is not None for n in named):
        if args.storey is None:
            raise DataError(f"{args.decisions}: its commits name storeys; pass --storey NAME "
                            "(the storey the recording was made on) to judge them")  # fmt: skip
        other = scored["storey"].notna() & (scored["storey"] != str(args.storey))
        scored.loc[other, "correct"] = False
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

        fp = load_floorplan(plan)
        if fp.storeys is not None:  # a model of several storeys: draw the walk's
            if args.storey is None:
                raise DataError(f"{plan}: several storeys; --plot draws one: pass --storey NAME")
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
