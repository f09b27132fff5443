"""Which storey am I on: walks on towers and on real multi-storey IFC models, decided against
the whole building (every storey at once), and the wrong-storey fault.

Runs (``python -m experiments.storeys``):

* ``tower``: the procedural tower family (``sim.families.tower``: ``typical``, ``one_room``,
  ``rotated``), one walk per storey, each decided against the building's stacked plan;
* ``ifc``: random tours on every storey of the IFC models in the data folder that have two or
  more storeys with walls and spaces, decided against the whole model;
* ``wrong storey``: the same walks decided against one other storey's plan alone (the user
  passed ``--storey`` of another floor); only pairs of storeys that differ (a walk on a
  storey congruent to the one given is geometrically right and cannot be told from the
  scans; it is left out and counted).

Every walk goes through the robot's batch driver (``drive.batch``: the windows, the front-end
and the ``update`` a robot calls). Ground truth (the walk's storey and its poses in that
storey's frame) is read only to score: a COMMIT is right when it names the walk's storey and
places the robot within ``CORRECT_XY`` / ``CORRECT_YAW_DEG``; any other COMMIT is false.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from mfcl_jax.score.decisions import score_decisions

__all__ = ["Walk", "tower_walks", "ifc_walks", "decide_walks", "judge", "summary_table"]

IFC_FILES = ("Office_A_20110811.ifc", "Duplex_A_20110907_Architecture.ifc", "AC20-FZK-Haus.ifc")


@dataclass(frozen=True)
class Walk:
    """One walk to decide: ``plan`` (what the robot is given), the recording, the storey it
    is truly on (``storey``; scoring only), whether another storey is congruent to it, and
    table labels."""

    run: str
    family: str
    plan: object
    rec: object
    storey: str
    congruent: bool
    storeys: tuple = ()  # the building's (name, plan) in each storey's own frame
    tiles: tuple = ()  # the place of each storey in the building's stacked plan
    fault: str = ""


def tower_walks(kinds, seeds, n_storeys: int) -> list[Walk]:
    """One walk per storey of every tower (the storey's walks taken in turn)."""
    from mfcl_jax.floorplan.storeys import stack_storeys
    from mfcl_jax.sim import SimParams
    from mfcl_jax.sim.families.tower import make_tower
    from mfcl_jax.sources.simulated import simulate

    out = []
    for kind in kinds:
        for seed in seeds:
            tw = make_tower(kind, int(seed), n_storeys)
            plan, st = stack_storeys(tw.storeys, name=tw.name)
            for s, scene in enumerate(tw.scenes):
                names = sorted(scene.trajectories)
                w = names[s % len(names)]
                rec = simulate(scene, [w], [1000 * int(seed) + s], SimParams())[0]
                out.append(Walk(f"{tw.name}/{st.names[s]}/{w}", f"tower:{kind}", plan, rec,
                                st.names[s], bool(tw.congruent[s]), tuple(tw.storeys),
                                tuple(int(t) for t in st.tile)))  # fmt: skip
    return out


def ifc_walks(data, tours: int, seed: int = 0) -> list[Walk]:
    """``tours`` random tours on every storey of each multi-storey IFC model."""
    from mfcl_jax.floorplan.load import load_floorplan
    from mfcl_jax.sim import SimParams
    from mfcl_jax.sim.scenes import Scene
    from mfcl_jax.sources.simulated import simulate
    from mfcl_jax.sources.walks import random_tours

    out = []
    for f in IFC_FILES:
        path = data / "ifc" / f
        if not path.is_file():
            continue
        plan = load_floorplan(path)
        st = plan.storeys
        if st is None:
            continue
        own = tuple((name, load_floorplan(path, storey=name)) for name in st.names)
        for s, (name, fp) in enumerate(own):
            walks = random_tours(fp, tours, seed=2000 + seed + s)
            if not walks:
                continue
            trajs = {f"tour{i}": w for i, w in enumerate(walks)}
            recs = simulate(Scene(fp.name, fp, np.zeros((0, 2, 2)), trajs), list(trajs),
                            [seed + s], SimParams())  # fmt: skip
            congruent = st.shared(int(st.tile[s]))
            for w, rec in zip(trajs, recs, strict=True):
                out.append(Walk(f"{path.stem}/{name}/{w}", f"ifc:{path.stem}", plan, rec, name,
                                congruent, own, tuple(int(t) for t in st.tile)))  # fmt: skip
    return out


def meets(walk: Walk, other: int) -> bool:
    """Whether the walk passes where its storey's plan and storey ``other``'s differ: a room
    of its path within 0.3 m of walls that one plan has and the other lacks (beyond 0.1 m)."""
    s = [n for n, _ in walk.storeys].index(walk.storey)
    a, b = walk.storeys[s][1], walk.storeys[other][1]
    wa, wb = a.wall_solid, b.wall_solid
    diff = wa.difference(wb.buffer(0.1)).union(wb.difference(wa.buffer(0.1)))
    if diff.area < 1e-3:
        return False
    seen = {r for r in a.room_at(walk.rec.truth.poses[::5, :2]) if r is not None}
    return any(a.room(r).polygon.buffer(0.3).intersects(diff) for r in seen)


def tells_apart(walk: Walk) -> bool:
    """The walk passes a difference between its storey and every storey not congruent to
    it (``meets``): the scans can name its storey."""
    s = [n for n, _ in walk.storeys].index(walk.storey)
    tiles = walk.tiles
    return all(meets(walk, o) for o in range(len(tiles)) if tiles[o] != tiles[s])


GIVEN, ALONE = "wrong storey given", "wrong storey's plan alone"


def wrong_storey(walks: list[Walk]) -> tuple[list[Walk], int]:
    """Each walk decided with another storey named (the next one up, wrapping, that is not
    congruent to the walk's and differs from it where the walk passes: ``meets``) two ways:
    ``GIVEN``, as ``mfcl localize --storey`` does (every storey weighed, the named one marked
    given), and ``ALONE``, against that storey's plan only (a plan exported for one floor).
    ``(walks, left out)``: a walk with no such storey is left out (nothing it scans can tell
    the storey named from its own)."""
    from mfcl_jax.floorplan.storeys import stack_storeys

    out, left, stacked = [], 0, {}
    for w in walks:
        st = w.plan.storeys
        s = st.names.index(w.storey)
        others = [(s + d) % len(st.names) for d in range(1, len(st.names))]
        others = [o for o in others if st.tile[o] != st.tile[s] and meets(w, o)]
        if not others:
            left += 1
            continue
        name, plan = w.storeys[others[0]]
        key = (w.plan.name, name)
        if key not in stacked:
            stacked[key] = stack_storeys(list(w.storeys), name=w.plan.name, given=name)[0]
        for fault, p in ((GIVEN, stacked[key]), (ALONE, plan)):
            out.append(Walk(w.run + f"@{name}", w.family, p, w.rec, w.storey, w.congruent,
                            w.storeys, w.tiles, fault=fault))  # fmt: skip
    return out, left


def decide_walks(walks: list[Walk], progress=None) -> tuple[list[list], float]:
    """Every walk's decision records (``drive.batch``, in the walks' order) and the seconds."""
    from mfcl_jax.drive.batch import decide_batch

    t0 = time.perf_counter()
    out: list = [None] * len(walks)
    for i, res in decide_batch([w.plan for w in walks], [w.rec.seq for w in walks],
                               progress=progress):  # fmt: skip
        out[i] = res.records
    return out, time.perf_counter() - t0


def judge(walk: Walk, records: list, apart: bool) -> dict:
    """One row: the walk's windows, COMMIT windows right and false, AMBIGUOUS(storey) windows,
    the first right commit (window, distance travelled) and the final state; ``apart``:
    whether the walk passes what tells its storey from the others (``tells_apart``)."""
    truth, seq = walk.rec.truth, walk.rec.seq
    df = score_decisions(records, seq.times, seq.odometry, truth.times, truth.poses,
                         where=walk.run)  # fmt: skip
    amb_storey = int(((df["state"] == "AMBIGUOUS") & (df["symmetry"] == "storey")).sum())
    com = df[df["state"] == "COMMIT"]
    # a commit names the walk's storey: in the stacked plan its `storey`; on a plan of one
    # storey, that storey (right unless it is the wrong one given: the fault)
    named = com["storey"] if walk.plan.storeys is not None else walk.storey
    ok = com["correct"].to_numpy(bool) & (named == walk.storey) & (not walk.fault)
    ok = np.asarray(ok, bool)
    right, false = int(ok.sum()), int((~ok).sum())
    first = None
    if right:
        dist = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(truth.poses[:, :2], axis=0).T))])
        row = com[ok].iloc[0]
        first = (int(row["k"]), float(np.interp(row["t"], truth.times, dist)))
    return dict(
        run=walk.run, family=walk.family, storey=walk.storey, congruent=walk.congruent,
        fault=walk.fault or "-", tells_apart=apart, windows=len(records), commit_right=right,
        commit_false=false,
        ambiguous_storey=amb_storey, first_right_k=None if first is None else first[0],
        first_right_m=None if first is None else round(first[1], 1),
        final=records[-1]["state"] if records else "-",
        final_kind=(records[-1]["symmetry"] or "-") if records else "-",
    )  # fmt: skip


def summary_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per family, fault and storey class (congruent or not): walks, walks with a false
    commit, walks committed right, walks ending AMBIGUOUS(storey), the median distance to the
    first right commit."""
    cls = np.where(rows["congruent"], "congruent storey",
                   np.where(rows["tells_apart"], "distinct, walk passes the difference",
                            "distinct, walk misses the difference"))  # fmt: skip
    g = rows.assign(cls=cls)
    out = g.groupby(["family", "fault", "cls"], sort=True).agg(
        walks=("run", "size"),
        false_commit_walks=("commit_false", lambda v: int((v > 0).sum())),
        committed_right=("commit_right", lambda v: int((v > 0).sum())),
        ending_ambiguous_storey=("final_kind", lambda v: int((v == "storey").sum())),
        median_first_commit_m=("first_right_m", "median"),
    )
    return out.reset_index().rename(columns={"cls": "storey class"})
