"""The three ways ``mfcl localize`` runs: one input streamed window by window, many datasets
in one batch, and ``--follow`` (a folder being written).

Each checks its outputs before it reads anything, reads and computes everything before it
writes, and prints: per-window status lines (``status.status_line``), notes on stderr,
progress on stderr when a person watches (``progress.Progress``).
"""

from __future__ import annotations

import sys
from pathlib import Path

from mfcl_jax.io.errors import DataError
from mfcl_jax.robot.progress import COMPILING, Progress

__all__ = ["localize", "localize_one", "localize_many", "follow"]


def _params(args):
    from dataclasses import replace

    from mfcl_jax.robot.localizer import LocalizeParams

    p = LocalizeParams().with_d_s(args.d_s)
    if getattr(args, "no_scan_match", False):
        sm = replace(p.window.scan_match, enabled=False)
        p = replace(p, window=replace(p.window, scan_match=sm))
    return p


def _start(progress: Progress) -> None:
    """Imports JAX and the localizer and turns the compilation cache on."""
    with progress.stage("starting (loading JAX)"):
        import mfcl_jax.robot.localizer  # noqa: F401  (the slow imports, inside the stage)
        from mfcl_jax.robot.compile_cache import enable_cache

        enable_cache()


def _err(text: str) -> None:
    print(text, file=sys.stderr)


def localize(args, progress: Progress) -> int:
    """``mfcl localize``: checks the flags and runs the matching mode."""
    from mfcl_jax.cli.inputs import dataset_folders

    if not args.d_s > 0:
        raise DataError(f"localize: --d-s must be > 0, got {args.d_s}")
    if args.out is not None and args.out_dir is not None:
        raise DataError(f"localize: give --out ({args.out}) or --out-dir ({args.out_dir})")
    if args.follow is not None:
        return follow(args, progress)
    folders = dataset_folders(args)
    if len(folders) > 1:
        return localize_many(args, folders, progress)
    return localize_one(args, folders, progress)


def _check_viz(path: Path, inputs) -> None:
    """``--viz``: an ``.mcap`` name that is none of the run's inputs and outputs and can be
    written (checked before any work, like the decisions file)."""
    from mfcl_jax.io import check_output

    if path.suffix.lower() != ".mcap":
        raise DataError(f"{path}: --viz writes an MCAP file; give a name ending in .mcap")
    check_output(path, inputs=inputs)


def _summary(records) -> tuple[int | None, str | None]:
    first = next((d["k"] for d in records if d["state"] == "COMMIT"), None)
    return first, records[-1]["state"] if records else None


def _verdict(records) -> str:
    """``"8 windows in 2 odometry segments, first COMMIT at window 3, final state DEFER"``."""
    k, last = _summary(records)
    n_seg = len({d.get("segment", 0) for d in records})
    segs = f" in {n_seg} odometry segments" if n_seg > 1 else ""
    verdict = f"first COMMIT at window {k}" if k else "no commit"
    return f"{len(records)} windows{segs}, {verdict}, final state {last or 'none'}"


def _stopped(stop, what: str) -> None:
    from mfcl_jax.cli.signals import stop_name, stop_status

    _err(f"mfcl: stopped by {stop_name(stop)}: {what}; exit status {stop_status(stop)}")


def localize_one(args, folders, progress: Progress) -> int:
    """One dataset folder, bag or CARMEN log, streamed window by window. Ctrl-C or SIGTERM
    stops it: the windows decided so far are written (and ``--viz``), exit 130 or 143."""
    from mfcl_jax.cli.inputs import input_paths
    from mfcl_jax.cli.signals import StopSignals, stop_status
    from mfcl_jax.io import check_output, write_decisions

    src = folders[0] if folders else (args.bag or args.carmen)
    out = args.out or Path("decisions.jsonl")
    if args.out_dir is not None and src is not None:
        out = args.out_dir / f"{Path(src).name.split('.')[0] or 'decisions'}.jsonl"
    if out.is_dir():
        raise DataError(f"{out}: --out is a folder, expected a file name")
    check_output(out, inputs=input_paths(args, folders))
    if args.viz is not None:
        _check_viz(args.viz, [*input_paths(args, folders), out])
    records, state, stop = [], {"viz": None}, None
    with StopSignals() as signals:
        try:
            _run_one(args, folders, progress, src, records, state)
        except KeyboardInterrupt as e:
            stop = e
        viz = state["viz"]
        with signals.writing():
            write_decisions(out, records)
            shown = f"; viz: {viz.close()}" if viz is not None else ""
    if stop is not None and args.viz is not None and viz is None:
        _err(f"mfcl: {args.viz} not written: stopped before the floor plan was loaded")
    print(f"{_verdict(records)}; decisions: {out}{shown}")
    if stop is not None:
        _stopped(stop, f"{len(records)} windows decided, written to {out}{shown}")
        return stop_status(stop)
    return 0


def _run_one(args, folders, progress, src, records: list, state: dict) -> None:
    """``localize_one``'s work: appends each window's record to ``records``;
    ``state["viz"]`` holds the viz writer (None without ``--viz``)."""
    _start(progress)
    from mfcl_jax.cli.inputs import load_input
    from mfcl_jax.cli.segments import Splits
    from mfcl_jax.robot.localizer import Localizer
    from mfcl_jax.robot.viz import VizWriter

    with progress.stage(f"loading {src}"):
        fp, seq, notes = load_input(args, folders)
    for note in notes:
        _err(note)
    viz = None
    if args.viz is not None:  # the plan at the first scan's time; a time < 0 is refused here
        viz = VizWriter(args.viz, fp, start=float(min(seq.times)) if len(seq) else None)
        state["viz"] = viz
    with progress.stage(f"preparing {fp.name} (features, gate maps)"):
        loc = Localizer(fp, _params(args))
    n = loc.estimate(seq)
    _err(f"{seq.source}: {len(seq)} scans, about {n} windows of {args.d_s:g} m; "
         f"floor plan {fp.name}")  # fmt: skip
    if any(float(v) for v in fp.offset):
        ox, oy = (float(v) for v in fp.offset)
        _err(f"{fp.name}: localized in a local frame; poses and anchors are given in the "
             f"plan frame (plan = local + ({ox:.3f}, {oy:.3f}))")  # fmt: skip
    if n == 0:
        _err("no complete window: the odometry travels less than d_s")
    splits = Splits(loc.params.window, seq.source)
    first = f"window 1 of {n}: {COMPILING}"
    for r in progress.track(loc.run(seq), n, first):
        records.append(r.record(fp.offset))
        if viz is not None:
            viz.add(r, records[-1])
        _note(splits.note(seq, r.k, r.segment, r.t, r.first, r.last))
        if not args.quiet:
            progress.echo(r.status(fp.offset))
            sys.stdout.flush()


def _note(line: str | None) -> None:
    """A split note on stderr, after the status lines printed so far."""
    if line:
        sys.stdout.flush()
        _err(line)


def localize_many(args, folders, progress: Progress) -> int:
    """Several dataset folders in one batch, one decisions file each (``--out-dir``).

    Every dataset is read before any is decided, and all the bad ones are named at once:
    without ``--keep-going`` nothing is decided (exit 2); with it the others are decided and
    written, and the exit status is 2. Ctrl-C or SIGTERM stops the batch: the datasets
    decided so far are written, exit 130 or 143."""
    from mfcl_jax.cli.inputs import check_inputs, input_paths
    from mfcl_jax.cli.signals import StopSignals, stop_status
    from mfcl_jax.io import check_output, write_decisions
    from mfcl_jax.robot.status import summary_table

    if args.out is not None:
        raise DataError(
            f"localize: --out {args.out} names one file but {len(folders)} datasets were given; "
            "use --out-dir D (one <dataset name>.jsonl each)"
        )
    if args.viz is not None:
        raise DataError(
            f"localize: --viz {args.viz} shows one run but {len(folders)} datasets were given; "
            "localize them one at a time for a viz file each"
        )
    check_inputs(args, folders)
    names: dict[str, Path] = {}
    for f in folders:
        if f.name in names:
            raise DataError(f"{f}: same dataset name as {names[f.name]}; their outputs collide")
        names[f.name] = f
    out_dir = args.out_dir or Path(".")
    outs = [out_dir / f"{f.name}.jsonl" for f in folders]
    inputs = input_paths(args, folders)
    for o in outs:
        check_output(o, inputs=inputs)
    results, bad, stop = {}, {}, None
    with StopSignals() as signals:
        try:
            _run_many(args, folders, progress, results, bad)
        except KeyboardInterrupt as e:
            stop = e
        with signals.writing():
            for i in sorted(results):
                write_decisions(outs[i], results[i].records)
    rows = []
    for i, f in enumerate(folders):
        if i in results:
            first, last = _summary(results[i].records)
            rows.append(dict(dataset=f.name, windows=len(results[i].records),
                             first_commit=first, final_state=last))  # fmt: skip
        else:
            why = "bad input" if i in bad else "not decided"
            rows.append(dict(dataset=f.name, windows="-", first_commit=None, final_state=why))
    print(summary_table(rows))
    print(f"decisions: {len(results)} files in {out_dir}")
    if stop is not None:
        left = len(folders) - len(results)
        _stopped(stop, f"{len(results)} of {len(folders)} datasets decided and written, {left} "
                 "not")  # fmt: skip
        return stop_status(stop)
    if bad:
        _err(f"mfcl: {len(bad)} of {len(folders)} datasets not decided (bad input, named "
             "above); exit status 2")  # fmt: skip
        return 2
    return 0


def _bad_inputs(folders, bad: dict) -> str:
    """One message naming every bad dataset (``bad``: index -> error)."""
    if len(bad) == 1:
        (msg,) = bad.values()
        return (f"{msg} (1 of {len(folders)} datasets; nothing was decided: pass --keep-going "
                "to decide the others)")  # fmt: skip
    lines = [f"  {folders[i]}: {m}" if str(folders[i]) not in m else f"  {m}"
             for i, m in sorted(bad.items())]  # fmt: skip
    return (f"{len(bad)} of {len(folders)} datasets cannot be used; nothing was decided (pass "
            "--keep-going to decide the others):\n" + "\n".join(lines))  # fmt: skip


def _run_many(args, folders, progress, results: dict, bad: dict) -> None:
    """``localize_many``'s work: reads every dataset (the bad ones into ``bad``, index ->
    error), then decides the good ones in one batch (into ``results``, index ->
    ``BatchResult``), printing their status lines."""
    from mfcl_jax.floorplan.model import FloorplanError

    _start(progress)
    from mfcl_jax.cli.inputs import load_dataset_input, planar_params
    from mfcl_jax.cli.segments import Splits
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.robot.status import status_line

    fp_opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    plan = load_floorplan(args.floorplan, storey=args.storey, **fp_opts) if args.floorplan else None
    planar = planar_params(args)
    loaded = {}
    for i, f in enumerate(folders):
        try:
            with progress.stage(f"loading {f}"):
                loaded[i] = load_dataset_input(args, f, plan, planar)
        except (DataError, FloorplanError, OSError) as e:
            bad[i] = str(e)
            continue
        for note in loaded[i][2]:
            _err(note)
    if bad and not args.keep_going:
        raise DataError(_bad_inputs(folders, bad))
    for i in sorted(bad):
        _err(f"mfcl: error: {bad[i]}")
    if bad and loaded:
        _err(f"mfcl: --keep-going: deciding the {len(loaded)} other datasets")
    params = _params(args)
    for i, res in _decide(args, loaded, params, progress, bad):
        f, seq = folders[i], loaded[i][1]
        results[i] = res
        splits = Splits(params.window, f)
        if not args.quiet:
            print(f"{f}: {len(seq)} scans, {len(res.records)} windows of {args.d_s:g} m")
        for d, detail in zip(res.records, res.details, strict=True):
            _note(splits.note(seq, d["k"], d.get("segment", 0), d["t"]))
            if not args.quiet:
                print(status_line(d, detail))
        sys.stdout.flush()


def _decide(args, loaded: dict, params, progress, bad: dict):
    """``(index, BatchResult)`` of the loaded datasets (``localize_batch``). A dataset the
    batch cannot decide (``DataError``) stops it; with ``--keep-going`` the datasets left
    are then decided one by one, and those that fail go into ``bad``."""
    from mfcl_jax.floorplan.model import FloorplanError
    from mfcl_jax.robot.many import localize_batch

    todo = sorted(loaded)
    if not todo:
        return
    done = set()
    try:
        fps, seqs = [loaded[i][0] for i in todo], [loaded[i][1] for i in todo]
        for j, res in localize_batch(fps, seqs, params, progress):
            done.add(todo[j])
            yield todo[j], res
        return
    except (DataError, FloorplanError) as e:
        if not args.keep_going:
            raise
        left = [i for i in todo if i not in done]
        if len(left) == 1:
            bad[left[0]] = str(e)
            _err(f"mfcl: error: {e}")
            return
    for i in left:
        try:
            for _, res in localize_batch([loaded[i][0]], [loaded[i][1]], params, progress):
                yield i, res
        except (DataError, FloorplanError) as e:
            bad[i] = str(e)
            _err(f"mfcl: error: {e}")


def follow(args, progress: Progress) -> int:
    """``--follow DIR``: decisions of a dataset folder that is being written, streamed; it
    stops after ``--idle-timeout`` s without new data, on Ctrl-C or on SIGTERM (exit 0 in
    every case), and writes ``--out`` (and ``--viz``) then."""
    from mfcl_jax.cli.inputs import check_inputs, input_paths, mount_flags, planar_params
    from mfcl_jax.cli.signals import StopSignals, stop_name
    from mfcl_jax.io import check_output, write_decisions
    from mfcl_jax.robot.live import Follower
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
        _check_viz(args.viz, [*input_paths(args, [folder]), args.out])
    follower = Follower(folder, planar, idle_timeout=args.idle_timeout)
    records, state = [], {"viz": None}
    why = f"no new data for {args.idle_timeout:g} s"
    with StopSignals() as signals:
        try:
            _run_follow(args, progress, follower, args.floorplan or plans[0], records, state)
        except KeyboardInterrupt as e:
            why = stop_name(e)
        with signals.writing():
            for line in follower.pending():
                _err(f"mfcl: warning: {line}")
            dim = f" ({follower.dim}-D)" if follower.dim else ""
            _err(f"stopped ({why}): {follower.n_scans} scans{dim}, {_verdict(records)}")
            if args.out is not None:
                write_decisions(args.out, records)
                _err(f"decisions: {args.out}")
            viz = state["viz"]
            if viz is not None:
                _err(f"viz: {viz.close()}")
            elif args.viz is not None and state.get("dropped") is None:
                _err(f"mfcl: {args.viz} not written: stopped before the floor plan was loaded")
    return 0


def _run_follow(args, progress, follower, plan, records: list, state: dict) -> None:
    """``follow``'s work: appends each window's record to ``records``; ``state["viz"]`` holds
    the viz writer (None without ``--viz`` or once dropped: ``state["dropped"]``)."""
    _start(progress)
    from mfcl_jax.cli.segments import Splits
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.io.decisions import decision_line
    from mfcl_jax.robot.localizer import Localizer
    from mfcl_jax.robot.viz import VizWriter

    opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    with progress.stage(f"loading {plan}"):
        fp = load_floorplan(plan, storey=args.storey, **opts)
    loc = Localizer(fp, _params(args))
    state["viz"] = VizWriter(args.viz, fp) if args.viz is not None else None
    folder = follower.folder
    _err(f"{folder}: following (stops after {args.idle_timeout:g} s without new data, on Ctrl-C "
         "or on SIGTERM)")  # fmt: skip
    splits = Splits(loc.params.window, folder)
    first = "window 1: waiting for a complete window, then " + COMPILING
    for r in progress.track(loc.follow(follower.prefixes()), None, first):
        records.append(r.record(fp.offset))
        if state["viz"] is not None:
            state["viz"] = _viz_add(state["viz"], r, records[-1])
            if state["viz"] is None:
                state["dropped"] = True
        sys.stdout.write(decision_line(records[-1]) + "\n")
        sys.stdout.flush()
        _note(splits.note(follower.sequence, r.k, r.segment, r.t, r.first, r.last))
        if not args.quiet:
            progress.echo(r.status(fp.offset), file=sys.stderr)


def _viz_add(viz, result, record):
    """Adds a window to a live run's viz file; a window the file cannot hold (a time < 0)
    drops the file with a warning, and the run goes on deciding."""
    if viz is None:
        return None
    try:
        viz.add(result, record)
    except DataError as e:
        _err(f"mfcl: warning: {e}; {viz.path} will not be written")
        viz.discard()
        return None
    return viz
