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


def localize_one(args, folders, progress: Progress) -> int:
    """One dataset folder, bag or CARMEN log, streamed window by window."""
    from mfcl_jax.cli.inputs import input_paths, load_input
    from mfcl_jax.io import check_output

    src = folders[0] if folders else (args.bag or args.carmen)
    out = args.out or Path("decisions.jsonl")
    if args.out_dir is not None and src is not None:
        out = args.out_dir / f"{Path(src).name.split('.')[0] or 'decisions'}.jsonl"
    if out.is_dir():
        raise DataError(f"{out}: --out is a folder, expected a file name")
    check_output(out, inputs=input_paths(args, folders))
    if args.viz is not None:
        _check_viz(args.viz, [*input_paths(args, folders), out])
    _start(progress)
    from mfcl_jax.io import write_decisions
    from mfcl_jax.robot.localizer import Localizer
    from mfcl_jax.robot.viz import VizWriter

    with progress.stage(f"loading {src}"):
        fp, seq, notes = load_input(args, folders)
    for note in notes:
        _err(note)
    viz = None
    if args.viz is not None:  # the plan at the first scan's time; a time < 0 is refused here
        viz = VizWriter(args.viz, fp, start=float(min(seq.times)) if len(seq) else None)
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
    records = []
    try:
        first = f"window 1 of {n}: {COMPILING}"
        for r in progress.track(loc.run(seq), n, first):
            records.append(r.record(fp.offset))
            if viz is not None:
                viz.add(r, records[-1])
            if not args.quiet:
                progress.echo(r.status(fp.offset))
    except KeyboardInterrupt:
        also = f" and {args.viz}" if viz is not None else ""
        _err(f"mfcl: interrupted after {len(records)} windows; {out}{also} not written")
        return 130
    write_decisions(out, records)
    shown = f"; viz: {viz.close()}" if viz is not None else ""
    k, last = _summary(records)
    verdict = f"first COMMIT at window {k}" if k else "no commit"
    print(f"{len(records)} windows, {verdict}, final state {last or 'none'}; decisions: {out}"
          + shown)  # fmt: skip
    return 0


def localize_many(args, folders, progress: Progress) -> int:
    """Several dataset folders in one batch, one decisions file each (``--out-dir``)."""
    from mfcl_jax.cli.inputs import check_inputs, input_paths, load_dataset_input, planar_params
    from mfcl_jax.io import check_output
    from mfcl_jax.robot.status import status_line, summary_table

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
    _start(progress)
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.io import write_decisions
    from mfcl_jax.robot.many import localize_batch

    fp_opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    plan = load_floorplan(args.floorplan, storey=args.storey, **fp_opts) if args.floorplan else None
    planar = planar_params(args)
    loaded = []
    for f in folders:
        with progress.stage(f"loading {f}"):
            loaded.append(load_dataset_input(args, f, plan, planar))
        for note in loaded[-1][2]:
            _err(note)
    fps, seqs = [fp for fp, _, _ in loaded], [s for _, s, _ in loaded]
    rows, results = [], {}
    for i, res in localize_batch(fps, seqs, _params(args), progress):
        f, seq = folders[i], seqs[i]
        results[i] = res
        if not args.quiet:
            print(f"{f}: {len(seq)} scans, {len(res.records)} windows of {args.d_s:g} m")
            for d, detail in zip(res.records, res.details, strict=True):
                print(status_line(d, detail))
            sys.stdout.flush()
        first, last = _summary(res.records)
        rows.append(dict(dataset=f.name, windows=len(res.records), first_commit=first,
                         final_state=last))  # fmt: skip
    for i, o in enumerate(outs):
        write_decisions(o, results[i].records)
    print(summary_table(rows))
    print(f"decisions: {len(outs)} files in {out_dir}")
    return 0


def follow(args, progress: Progress) -> int:
    """``--follow DIR``: decisions of a dataset folder that is being written, streamed."""
    from mfcl_jax.cli.inputs import check_inputs, input_paths, mount_flags, planar_params
    from mfcl_jax.io import check_output
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
    _start(progress)
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.io import write_decisions
    from mfcl_jax.io.decisions import decision_line
    from mfcl_jax.robot.live import Follower
    from mfcl_jax.robot.localizer import Localizer
    from mfcl_jax.robot.viz import VizWriter

    opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    with progress.stage(f"loading {args.floorplan or plans[0]}"):
        fp = load_floorplan(args.floorplan or plans[0], storey=args.storey, **opts)
    follower = Follower(folder, planar, idle_timeout=args.idle_timeout)
    loc = Localizer(fp, _params(args))
    viz = VizWriter(args.viz, fp) if args.viz is not None else None
    _err(f"{folder}: following (stops after {args.idle_timeout:g} s without new data or on Ctrl-C)")
    records, why = [], f"no new data for {args.idle_timeout:g} s"
    try:
        first = f"window 1: waiting for a complete window, then {COMPILING}"
        for r in progress.track(loc.follow(follower.prefixes()), None, first):
            records.append(r.record(fp.offset))
            viz = _viz_add(viz, r, records[-1])
            sys.stdout.write(decision_line(records[-1]) + "\n")
            sys.stdout.flush()
            if not args.quiet:
                progress.echo(r.status(fp.offset), file=sys.stderr)
    except KeyboardInterrupt:
        why = "Ctrl-C"
    for line in follower.pending():
        _err(f"mfcl: warning: {line}")
    k, last = _summary(records)
    verdict = f"first COMMIT at window {k}" if k else "no commit"
    dim = f" ({follower.dim}-D)" if follower.dim else ""
    _err(f"stopped ({why}): {follower.n_scans} scans{dim}, {len(records)} windows, {verdict}, "
         f"final state {last or 'none'}")  # fmt: skip
    if args.out is not None:
        write_decisions(args.out, records)
        _err(f"decisions: {args.out}")
    if viz is not None:
        _err(f"viz: {viz.close()}")
    return 0


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
