"""Many recordings decided in one call, within a memory budget (``mfcl localize A B C``).

The recordings are grouped by their plan's size class (``decision.runs.size_class``: the
raster side in steps of 256 cells and the rival search's image), so that a plan is padded to
the largest plan of its class, never to the largest of the call; the smallest class runs
first. Within a class the recordings are decided in chunks of one size (the last padded to
it: one compilation per class and chunk size): a chunk's windows are cut together
and registered by the class's ``FrontEnd`` (``drive.register``, the study's and the
benchmark's path too; the plan features of the chunk's plans dropped after it) and decided by the
one decision layer (``decision.runs``: ``vmap`` over runs of ``lax.scan(layer.update)``, the
``update`` a robot calls). The capacities are sized once, from every recording's input
odometry, before any work. Results are handed out chunk by chunk, as they are decided.

Memory: the resident peak of every chunk is measured (``memory.PeakSampler``) and held
against the budget; a chunk that passes it halves the chunk size of what follows (one more
compilation) and is reported in ``Report.over``. The budget is a limit the driver steers by,
not one the kernel enforces: one recording whose class alone needs more still runs.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import jax
import numpy as np

from mfcl_jax import windows as W
from mfcl_jax.drive.memory import PeakSampler, default_budget, gib, resident
from mfcl_jax.robot.localizer import LocalizeParams
from mfcl_jax.robot.progress import COMPILING, Progress
from mfcl_jax.robot.records import record_of

__all__ = ["BatchResult", "Report", "decide_batch", "CHUNK"]

CHUNK = 8  # recordings per chunk (at most)


@dataclass(frozen=True)
class BatchResult:
    """The windows of one recording.

    Attributes:
        records: one decisions-file record per window (``records.record_of``).
        details: per window, the status line's detail (points, candidates).
    """

    records: list
    details: list


@dataclass
class Report:
    """What a batch did: ``budget`` (bytes), ``peak`` (the highest resident memory of any
    chunk), ``chunks`` (one dict per chunk: plan class, recordings, rows, peak), ``over``
    (the chunks whose peak passed the budget)."""

    budget: int = 0
    peak: int = 0
    chunks: list = field(default_factory=list)

    @property
    def over(self) -> list:
        return [c for c in self.chunks if c["peak"] > self.budget]


def _floors(seqs, p: W.WindowParams) -> dict:
    """Capacities that hold every recording (from the input odometry, before scan matching,
    whose jump test can only split segments)."""
    n_win, n_kf, step, head = 1, 1, 16, 0
    for seq in seqs:
        kf = W.keyframes(seq.odometry, p.keyframe_spacing, p.keyframe_turn_deg)
        raw = np.asarray(seq.odometry, np.float64)[kf]
        seg = W.odometry_segments(raw, np.asarray(seq.times)[kf])
        b = W.segment_bounds(raw, seg, p.d_s, p.step)
        n_kf = max(n_kf, len(kf))
        if len(b):
            n_win = max(n_win, len(b))
            step = max(step, int(np.max(np.diff(b[:, 1]), initial=0)))
            head = max(head, int(np.max(b[:, 1] - b[:, 0] + 1)))
    step = -(-step // 16) * 16
    return dict(min_windows=n_win, min_traj=n_kf, min_step=step,
                min_head=-(-max(head - step, 0) // 16) * 16)  # fmt: skip


def _classes(floorplans) -> list[list[int]]:
    """Recording indices grouped by their plan's size class, smallest class first."""
    from mfcl_jax.decision.runs import size_class

    of_plan: dict = {}
    groups: dict = {}
    for i, fp in enumerate(floorplans):
        if id(fp) not in of_plan:
            of_plan[id(fp)] = size_class(fp)
        groups.setdefault(of_plan[id(fp)], []).append(i)
    return [groups[k] for k in sorted(groups)]


def decide_batch(floorplans, seqs, params: LocalizeParams | None = None, progress=None,
                 budget: int | None = None, chunk: int | None = None,
                 report: Report | None = None) -> Iterator[tuple[int, BatchResult]]:  # fmt: skip
    """Decisions at every window of every sequence, chunk by chunk.

    Args:
        floorplans: the ``Floorplan`` of each sequence.
        seqs: ``ScanSequence``s.
        params: ``LocalizeParams`` (shared).
        progress: ``Progress`` for stages (default: silent).
        budget: bytes of resident memory to stay within (default ``memory.default_budget``).
        chunk: the most recordings decided together (default ``CHUNK``).
        report: a ``Report`` filled as the batch runs (peaks per chunk).

    Yields:
        ``(index, BatchResult)`` per sequence, chunk by chunk (the classes' order, not the
        input's).
    """
    from mfcl_jax.decision.lanes import make_lanes
    from mfcl_jax.decision.runs import stack_buildings

    params = params or LocalizeParams()
    progress = progress or Progress(False)
    report = report if report is not None else Report()
    report.budget = int(budget or default_budget())
    size = max(1, min(chunk or CHUNK, len(seqs)))
    floors = _floors(seqs, params.window)
    p, lanes, spec = make_lanes(params.decision, (params.policy,), baselines=False,
                                primary=params.policy)  # fmt: skip
    classes = _classes(floorplans)
    done = 0
    for c, members in enumerate(classes, 1):
        plans = list({id(floorplans[i]): floorplans[i] for i in members}.values())
        where = f"plan class {c} of {len(classes)} ({len(plans)} plans, {len(members)} recordings)"
        with progress.stage(f"{where}: decision maps"):
            buildings = stack_buildings(plans, spec)
        state = _Class(plans, buildings, p, lanes, spec, floors, params)
        todo = list(members)
        # chunks of one size (20 recordings, at most 8: 7, 7, 6), the last padded to it
        rows = math.ceil(len(todo) / math.ceil(len(todo) / size))
        while todo:
            part, todo = todo[:rows], todo[rows:]
            first = "registering" if rows in state.compiled else COMPILING
            text = f"{where}: recordings {done + 1}-{done + len(part)} of {len(seqs)} ({first})"
            with progress.stage(text), PeakSampler() as peak:
                out = state.decide(floorplans, seqs, part, rows)
            state.compiled.add(rows)
            done += len(part)
            report.peak = max(report.peak, peak.peak)
            report.chunks.append(dict(plan_class=c, recordings=len(part), rows=rows,
                                      peak=peak.peak))  # fmt: skip
            if peak.peak > report.budget and rows > 1:
                size = max(1, rows // 2)
                rows = math.ceil(len(todo) / math.ceil(len(todo) / size)) if todo else size
                progress.note(
                    f"memory: {gib(peak.peak)} at its peak, above the budget of "
                    f"{gib(report.budget)}: {size} recordings per chunk from now on"
                )
            yield from out
        del state, buildings
    report.peak = max(report.peak, resident())


class _Class:
    """The plans of one size class: their front-end (features per chunk) and decision maps."""

    def __init__(self, plans, buildings, p, lanes, spec, floors, params):
        from mfcl_jax.frontend.driver import FrontEnd

        self.plans, self.buildings = plans, buildings
        self.p, self.lanes, self.spec, self.params = p, lanes, spec, params
        self.floors = dict(floors)
        self.steps = {k: self.floors.pop(k) for k in ("min_step", "min_head")}
        self.fe = FrontEnd(plans, params.frontend, chunk=16)
        self.compiled: set = set()  # chunk sizes run so far

    def decide(self, floorplans, seqs, idx, size) -> list:
        """``(index, BatchResult)`` of the recordings ``idx`` (padded to ``size`` rows)."""
        from mfcl_jax.decision.inputs import run_inputs
        from mfcl_jax.decision.runs import decide_runs
        from mfcl_jax.drive.register import register

        params = self.params
        index = {id(fp): b for b, fp in enumerate(self.plans)}
        group = [(seqs[i], params.window, index[id(floorplans[i])]) for i in idx]
        reg = register([group], self.fe, capacity=W.bucket(params.window.capacity, 256),
                       rows=size, keep=True)  # fmt: skip
        self.fe.release()  # the chunk's plan features
        batch, cands = reg.batch, reg.cands
        done = {i: BatchResult([], []) for i in idx}
        if batch.submaps.n:
            dec, _ = decide_runs(run_inputs(batch, cands, **self.steps), batch.run_building,
                                 self.plans, self.p, self.lanes, self.spec, min_runs=size,
                                 buildings=self.buildings, **self.floors)  # fmt: skip
            valid = np.asarray(cands.mask).sum(1)
            for r, (i, w) in enumerate(zip(idx, reg.windows, strict=True)):
                res, offset, st = done[i], floorplans[i].offset, floorplans[i].storeys
                for k in range(len(w)):
                    d = jax.tree.map(lambda a, r=r, k=k: a[r, k, 0], dec)
                    seg = int(w.segments[w.bounds[k, 0]])  # k + 1: over the whole recording
                    res.records.append(record_of(d, k + 1, float(w.t[k]), w.X[k], w.X_input[k],
                                                 offset, seg, params.unique_llr, st))  # fmt: skip
                    sub = int(batch.runs.submap[r, k])
                    thin = f" rethinned voxel={w.voxel[k]:.2f}" if W.rethinned(w)[k] else ""
                    res.details.append(f"pts={len(w.points[k])}{thin} cands={int(valid[sub])}")
        return [(i, done[i]) for i in idx]
