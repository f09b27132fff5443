"""``mfcl localize --follow DIR``: a dataset folder that is being written, decided as its
windows complete, the decisions streamed as JSON lines on stdout."""

from __future__ import annotations

import sys

from mfcl_jax.cli.common import check_viz, err, localize_params, split_note, start, verdict, viz_add
from mfcl_jax.io.errors import DataError
from mfcl_jax.robot.progress import COMPILING, Progress

__all__ = ["follow"]


def follow(args, progress: Progress) -> int:
    """``--follow DIR``: decisions of a dataset folder that is being written, streamed; it
    stops after ``--idle-timeout`` s without new data (exit 0), on Ctrl-C or on SIGTERM (exit
    0), or at a bad input (a scan or odometry line that cannot be read: exit 2, the error
    named), and writes ``--out`` (and ``--viz``) with what was decided, whatever stopped it."""
    from mfcl_jax.cli.inputs import check_inputs, input_paths, mount_flags, planar_params
    from mfcl_jax.io import check_output, write_decisions
    from mfcl_jax.robot.live import Follower
    from mfcl_jax.robot.signals import StopSignals, stop_name
    from mfcl_jax.sources.dataset import FLOORPLAN_NAMES

    folder = args.follow
    if args.dataset or args.bag is not None or args.carmen is not None:
        raise DataError(f"localize: --follow {folder} reads that folder only; give no other input")
    if args.out_dir is not None:
        raise DataError("localize: --follow writes one file: give --out, not --out-dir")
    if not folder.is_dir():
        raise DataError(f"{folder}: dataset folder not found")
    if not args.idle_timeout > 0:
        raise DataError(f"localize: --idle-timeout must be > 0 s, got {args.idle_timeout}")
    check_inputs(args, [folder])
    planar = planar_params(args, mount_flags(args)[1])
    plans = [folder / n for n in FLOORPLAN_NAMES if (folder / n).is_file()]
    if args.floorplan is None and len(plans) != 1:
        found = [p.name for p in plans] or "none"
        raise DataError(
            f"{folder}: --follow needs the floor plan first: exactly one of {FLOORPLAN_NAMES} "
            f"(found {found}), or --floorplan F"
        )
    if args.out is not None:
        check_output(args.out, inputs=input_paths(args, [folder]))
    if args.viz is not None:
        check_viz(args.viz, [*input_paths(args, [folder]), args.out])
    follower = Follower(folder, planar, idle_timeout=args.idle_timeout)
    records, state = [], {"viz": None}
    why, code = f"no new data for {args.idle_timeout:g} s", 0
    with StopSignals() as signals:
        try:
            stop = signals.run(
                lambda: _run_follow(
                    args, progress, follower, args.floorplan or plans[:1], records, state
                )
            )
            if stop is not None:
                why = stop_name(stop)
        except DataError as e:
            err(f"mfcl: error: {e}")
            why, code = "bad input, named above; exit status 2", 2
        with signals.writing():
            for line in follower.pending():
                err(f"mfcl: warning: {line}")
            dim = f" ({follower.dim}-D)" if follower.dim else ""
            err(f"stopped ({why}): {follower.n_scans} scans{dim}, {verdict(records)}")
            if args.out is not None:
                write_decisions(args.out, records)
                err(f"decisions: {args.out}")
            viz = state["viz"]
            if viz is not None:
                err(f"viz: {viz.close()}")
            elif args.viz is not None and state.get("dropped") is None:
                err(f"mfcl: {args.viz} not written: stopped before the floor plan was loaded")
    return code


def _run_follow(args, progress, follower, plan, records: list, state: dict) -> None:
    """``follow``'s work: appends each window's record to ``records``; ``state["viz"]`` holds
    the viz writer (None without ``--viz`` or once dropped: ``state["dropped"]``)."""
    start(progress)
    from mfcl_jax.cli.segments import Splits
    from mfcl_jax.floorplan.load import load_building
    from mfcl_jax.io.decisions import decision_line
    from mfcl_jax.robot.localizer import Localizer
    from mfcl_jax.robot.signals import atomic
    from mfcl_jax.robot.viz import VizWriter

    opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    with progress.stage(f"loading {' + '.join(str(p) for p in plan)}"):
        fp = load_building(plan, storey=args.storey, **opts)
    loc = Localizer(fp, localize_params(args))
    state["viz"] = VizWriter(args.viz, fp) if args.viz is not None else None
    folder = follower.folder
    err(f"{folder}: following (stops after {args.idle_timeout:g} s without new data, on Ctrl-C "
         "or on SIGTERM)")  # fmt: skip
    splits = Splits(loc.params.window, folder)
    first = "window 1: waiting for a complete window, then " + COMPILING
    for r in progress.track(loc.follow(follower.prefixes()), None, first):
        with atomic():  # a window is kept and streamed, or neither
            records.append(r.record(fp.offset))
            if state["viz"] is not None:
                state["viz"] = viz_add(state["viz"], r, records[-1])
                if state["viz"] is None:
                    state["dropped"] = True
            sys.stdout.write(decision_line(records[-1]) + "\n")
            sys.stdout.flush()
            split_note(splits.note(follower.sequence, r.k, r.segment, r.t, r.first, r.last))
            if not args.quiet:
                progress.echo(r.status(fp.offset), file=sys.stderr)
