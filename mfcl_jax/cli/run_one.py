"""``mfcl localize`` on one input (a dataset folder, a ROS bag or a CARMEN log), streamed
window by window; Ctrl-C or SIGTERM write what was decided."""

from __future__ import annotations

import sys
from pathlib import Path

from mfcl_jax.cli.common import check_viz, err, localize_params, split_note, start, stopped, verdict
from mfcl_jax.io.errors import DataError
from mfcl_jax.robot.progress import COMPILING, Progress

__all__ = ["localize_one"]


def localize_one(args, folders, progress: Progress) -> int:
    """One dataset folder, bag or CARMEN log, streamed window by window. Ctrl-C or SIGTERM
    stops it: the windows decided so far are written (and ``--viz``), exit 130 or 143."""
    from mfcl_jax.cli.inputs import input_paths
    from mfcl_jax.io import check_output, write_decisions
    from mfcl_jax.robot.signals import StopSignals, stop_status

    src = folders[0] if folders else (args.bag or args.carmen)
    out = args.out or Path("decisions.jsonl")
    if args.out_dir is not None and src is not None:
        out = args.out_dir / f"{Path(src).name.split('.')[0] or 'decisions'}.jsonl"
    if out.is_dir():
        raise DataError(f"{out}: --out is a folder, expected a file name")
    check_output(out, inputs=input_paths(args, folders))
    if args.viz is not None:
        check_viz(args.viz, [*input_paths(args, folders), out])
    records, state = [], {"viz": None}
    with StopSignals() as signals:
        stop = signals.run(lambda: _run_one(args, folders, progress, src, records, state))
        viz = state["viz"]
        with signals.writing():
            write_decisions(out, records)
            shown = f"; viz: {viz.close()}" if viz is not None else ""
    if stop is not None and args.viz is not None and viz is None:
        err(f"mfcl: {args.viz} not written: stopped before the floor plan was loaded")
    print(f"{verdict(records)}; decisions: {out}{shown}")
    if stop is not None:
        stopped(stop, f"{len(records)} windows decided, written to {out}{shown}")
        return stop_status(stop)
    return 0


def _run_one(args, folders, progress, src, records: list, state: dict) -> None:
    """``localize_one``'s work: appends each window's record to ``records``;
    ``state["viz"]`` holds the viz writer (None without ``--viz``)."""
    start(progress)
    from mfcl_jax.cli.inputs import load_input
    from mfcl_jax.cli.segments import Splits
    from mfcl_jax.robot.localizer import Localizer
    from mfcl_jax.robot.signals import atomic
    from mfcl_jax.robot.viz import VizWriter

    with progress.stage(f"loading {src}"):
        fp, seq, notes = load_input(args, folders)
    for note in notes:
        err(note)
    viz = None
    if args.viz is not None:  # the plan at the first scan's time; a time < 0 is refused here
        viz = VizWriter(args.viz, fp, start=float(min(seq.times)) if len(seq) else None)
        state["viz"] = viz
    with progress.stage(f"preparing {fp.name} (features, gate maps)"):
        loc = Localizer(fp, localize_params(args))
    n = loc.estimate(seq)
    err(f"{seq.source}: {len(seq)} scans, about {n} windows of {args.d_s:g} m; "
         f"floor plan {fp.name}")  # fmt: skip
    if any(float(v) for v in fp.offset):
        ox, oy = (float(v) for v in fp.offset)
        err(f"{fp.name}: localized in a local frame; poses and anchors are given in the "
             f"plan frame (plan = local + ({ox:.3f}, {oy:.3f}))")  # fmt: skip
    if n == 0:
        err("no complete window: the odometry travels less than d_s")
    splits = Splits(loc.params.window, seq.source)
    first = f"window 1 of {n}: {COMPILING}"
    for r in progress.track(loc.run(seq), n, first):
        with atomic():  # a window is kept and shown, or neither
            records.append(r.record(fp.offset))
            if viz is not None:
                viz.add(r, records[-1])
            split_note(splits.note(seq, r.k, r.segment, r.t, r.first, r.last))
            if not args.quiet:
                progress.echo(r.status(fp.offset))
                sys.stdout.flush()
