"""``mfcl localize`` on several dataset folders in one batch: every dataset checked first,
one decisions file each (``--out-dir``), ``--keep-going`` past bad ones."""

from __future__ import annotations

import sys
from pathlib import Path

from mfcl_jax.cli.common import err, localize_params, split_note, start, stopped, summary
from mfcl_jax.io.errors import DataError
from mfcl_jax.robot.progress import Progress

__all__ = ["localize_many"]


def localize_many(args, folders, progress: Progress) -> int:
    """Several dataset folders in one batch, one decisions file each (``--out-dir``).

    Every dataset is read before any is decided, and all the bad ones are named at once:
    without ``--keep-going`` nothing is decided (exit 2); with it the others are decided and
    written, and the exit status is 2. Each dataset's file is written the moment it is
    decided (``drive.batch``, within ``--max-memory``). Ctrl-C or SIGTERM stops the batch:
    the datasets decided so far are written, exit 130 or 143."""
    from mfcl_jax.cli.inputs import check_inputs, input_paths
    from mfcl_jax.drive.batch import Report
    from mfcl_jax.drive.memory import gib, parse_size
    from mfcl_jax.io import check_output, write_decisions
    from mfcl_jax.robot.signals import StopSignals, stop_status
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
    budget = parse_size(args.max_memory) if args.max_memory is not None else None
    results, bad, report = {}, {}, Report()

    def decided(i, res) -> None:  # written the moment it is decided: a kill keeps it
        with signals.writing():
            write_decisions(outs[i], res.records)
            results[i] = res
        signals.arm()

    with StopSignals() as signals:
        stop = signals.run(lambda: _run_many(args, folders, progress, bad, decided, budget,
                                             report))  # fmt: skip
    rows = []
    for i, f in enumerate(folders):
        if i in results:
            first, last = summary(results[i].records)
            rows.append(dict(dataset=f.name, windows=len(results[i].records),
                             first_commit=first, final_state=last))  # fmt: skip
        else:
            why = "bad input" if i in bad else "not decided"
            rows.append(dict(dataset=f.name, windows="-", first_commit=None, final_state=why))
    print(summary_table(rows))
    print(f"decisions: {len(results)} files in {out_dir}")
    if report.chunks:
        over = f"; {len(report.over)} chunks above it" if report.over else ""
        err(f"memory: {gib(report.peak)} at the peak, budget {gib(report.budget)} "
            f"({len(report.chunks)} chunks{over})")  # fmt: skip
    if stop is not None:
        left = len(folders) - len(results)
        stopped(stop, f"{len(results)} of {len(folders)} datasets decided and written, {left} "
                 "not")  # fmt: skip
        return stop_status(stop)
    if bad:
        err(f"mfcl: {len(bad)} of {len(folders)} datasets not decided (bad input, named "
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


def _run_many(args, folders, progress, bad: dict, decided, budget, report) -> None:
    """``localize_many``'s work: reads every dataset (the bad ones into ``bad``, index ->
    error), then decides the good ones in one batch (``decided(index, BatchResult)`` as each
    is decided), printing their status lines."""
    from mfcl_jax.floorplan.model import FloorplanError

    start(progress)
    from mfcl_jax.cli.inputs import load_dataset_input, planar_params
    from mfcl_jax.cli.segments import Splits
    from mfcl_jax.floorplan.load import load_building
    from mfcl_jax.robot.status import status_line

    fp_opts = dict(free_thresh=args.free_thresh, occupied_thresh=args.occupied_thresh)
    plan = load_building(args.floorplan, storey=args.storey, **fp_opts) if args.floorplan else None
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
            err(note)
    if bad and not args.keep_going:
        raise DataError(_bad_inputs(folders, bad))
    for i in sorted(bad):
        err(f"mfcl: error: {bad[i]}")
    if bad and loaded:
        err(f"mfcl: --keep-going: deciding the {len(loaded)} other datasets")
    params = localize_params(args)
    for i, res in _decide(args, loaded, params, progress, bad, budget, report):
        f, seq = folders[i], loaded[i][1]
        decided(i, res)
        splits = Splits(params.window, f)
        if not args.quiet:
            print(f"{f}: {len(seq)} scans, {len(res.records)} windows of {args.d_s:g} m")
        for d, detail in zip(res.records, res.details, strict=True):
            split_note(splits.note(seq, d["k"], d.get("segment", 0), d["t"]))
            if not args.quiet:
                print(status_line(d, detail))
        sys.stdout.flush()


def _decide(args, loaded: dict, params, progress, bad: dict, budget, report):
    """``(index, BatchResult)`` of the loaded datasets (``drive.batch``). A dataset the
    batch cannot decide (``DataError``) stops it; with ``--keep-going`` the datasets left
    are then decided one by one, and those that fail go into ``bad``."""
    from mfcl_jax.drive import batch
    from mfcl_jax.floorplan.model import FloorplanError

    todo = sorted(loaded)
    if not todo:
        return
    done = set()
    try:
        fps, seqs = [loaded[i][0] for i in todo], [loaded[i][1] for i in todo]
        for j, res in batch.decide_batch(fps, seqs, params, progress, budget, report=report):
            done.add(todo[j])
            yield todo[j], res
        return
    except (DataError, FloorplanError) as e:
        if not args.keep_going:
            raise
        left = [i for i in todo if i not in done]
        if len(left) == 1:
            bad[left[0]] = str(e)
            err(f"mfcl: error: {e}")
            return
    for i in left:
        try:
            for _, res in batch.decide_batch([loaded[i][0]], [loaded[i][1]], params, progress,
                                             budget, report=report):  # fmt: skip
                yield i, res
        except (DataError, FloorplanError) as e:
            bad[i] = str(e)
            err(f"mfcl: error: {e}")
