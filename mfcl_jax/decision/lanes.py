"""Lanes: the policies and threshold sets one evaluation decides side by side.

Every lane is our layer with traced flags and knobs, so one compiled ``update`` decides all
of them from one shared history:

* ``ours``: gate + independent consensus + lattice + probe + certification (the probe's
  aliases and every other explanation judged by the scans, ``certify``), floors from
  ``DecisionParams``;
* ``paper``: the paper's layer: as ``ours`` without the certification (an alias blocks a
  commit when the gate admits it);
* ``no_probe``: no alias probe and no certification (the lattice test on tied groups stays);
* ``consensus_only``: no gate anywhere; the probe re-gates aliases, so it goes too;
* ``ours_b2_d1``, ``ours_b4_d2``: commit floors ``(b_min, delta_min)`` = (2, 1), (4, 2)
  (``ours`` is (3, 2));
* ``ours_strict``: ``ours`` with the room-congruence threshold of the alias probe at 0.98
  (the paper's exact congruence) instead of 0.8 (``maps.MIN_CONGRUENT_IOU``);
* ``ours_unique``: ``ours`` that also commits, whatever the count of windows, where the path
  seen so far is explained by one placement and by no other (``uniqueness``, error rate
  ``alpha = 1e-3``); ``ours_unique_a1``, ``_a2``, ``_a4``, ``_a6``: the same at ``alpha`` =
  1e-1, 1e-2, 1e-4, 1e-6 (the test runs once per window for all of them);
* ``ours_grid``: ``ours`` that also commits where the evidence grid's leader (``grid``:
  every placement's accumulated log-likelihood, grown one window at a time) leads every
  other hill by ``GRID_MARGIN`` nats (``early``); ``ours_grid_off``: the grid kept and its
  margin reported, never committed on (what ``report.calibration.grid_calibration`` reads).

A lane reads one *mode* of the shared core: the gate on or off and one symmetry set of the
maps. The baselines (``baselines``) are lanes too, one per threshold set.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import numpy as np

from mfcl_jax.decision.params import DecisionParams, check_sets

__all__ = [
    "OURS_VARIANTS",
    "COUNT_VARIANTS",
    "UNIQUE_LANES",
    "ROBOT_POLICIES",
    "unique_threshold",
    "early_threshold",
    "BASELINES",
    "STRICT_IOU",
    "Lanes",
    "LaneSpec",
    "make_lanes",
]

# the evidence grid's commit margin (nats of its pooled model, ``grid``), calibrated on the
# benchmark's windows (``report.calibration``)
GRID_MARGIN = 4.0
GRID_OFF = 1e9  # a margin no grid reaches: the lane records the grid's margin, never commits on it
# name: (use_gate, use_probe, use_cert, b_min, delta_min, symmetry set, uniqueness alpha,
# grid margin); floors < 0: from DecisionParams; symmetry set 1 is the strict congruence
# threshold; alpha 0: no uniqueness test; margin 0: no evidence-grid test.
OURS_VARIANTS = {
    "ours": (True, True, True, -1.0, -1.0, 0, 0.0, 0.0),
    "paper": (True, True, False, -1.0, -1.0, 0, 0.0, 0.0),
    "no_probe": (True, False, False, -1.0, -1.0, 0, 0.0, 0.0),
    "consensus_only": (False, False, False, -1.0, -1.0, 0, 0.0, 0.0),
    "ours_b2_d1": (True, True, True, 2.0, 1.0, 0, 0.0, 0.0),
    "ours_b4_d2": (True, True, True, 4.0, 2.0, 0, 0.0, 0.0),
    "ours_strict": (True, True, True, -1.0, -1.0, 1, 0.0, 0.0),
    "ours_unique": (True, True, True, -1.0, -1.0, 0, 1e-3, 0.0),
    "ours_unique_a1": (True, True, True, -1.0, -1.0, 0, 1e-1, 0.0),
    "ours_unique_a2": (True, True, True, -1.0, -1.0, 0, 1e-2, 0.0),
    "ours_unique_a4": (True, True, True, -1.0, -1.0, 0, 1e-4, 0.0),
    "ours_unique_a6": (True, True, True, -1.0, -1.0, 0, 1e-6, 0.0),
    "ours_grid": (True, True, True, -1.0, -1.0, 0, 0.0, GRID_MARGIN),
    "ours_grid_off": (True, True, True, -1.0, -1.0, 0, 0.0, GRID_OFF),
}
# the variants the study and the tests decide by default: all but the uniqueness and grid lanes
COUNT_VARIANTS = tuple(n for n, v in OURS_VARIANTS.items() if v[6] == 0 and v[7] == 0)
# the uniqueness lanes by their error rate alpha
UNIQUE_LANES = {v[6]: n for n, v in OURS_VARIANTS.items() if v[6] > 0}
# what a robot may run: ours, alone or with the uniqueness test beside the count rule
ROBOT_POLICIES = ("ours", *UNIQUE_LANES.values(), "ours_grid")
BASELINES = ("single_shot", "support", "confidence", "gate_only")
STRICT_IOU = 0.98  # "exact copy up to 2 % modelling noise"


def unique_threshold(name: str) -> float:
    """The log-likelihood ratio ``log(1 / alpha)`` at which variant ``name``'s uniqueness test
    commits; 0 for a variant without the test."""
    alpha = OURS_VARIANTS[name][6]
    return float(np.log(1.0 / alpha)) if alpha > 0 else 0.0


def early_threshold(name: str) -> float:
    """What variant ``name``'s early test must reach to commit: ``log(1 / alpha)`` of the
    uniqueness test, or the evidence grid's margin; 0 for a variant without one."""
    return float(OURS_VARIANTS[name][7]) or unique_threshold(name)


@dataclass(frozen=True)
class Lanes:
    """Traced flags and knobs of our lanes, each ``(L,)``, and the baselines' knobs ``(S,)``.

    ``mode`` indexes ``LaneSpec.modes``: the (gate, symmetry set) pairs the core is
    computed for.
    """

    use_gate: jax.Array
    use_probe: jax.Array
    use_cert: jax.Array
    b_min: jax.Array
    delta_min: jax.Array
    cert_margin: jax.Array
    mode: jax.Array
    use_unique: jax.Array
    unique_llr: jax.Array  # log(1 / alpha) of the uniqueness test (0 where unused)
    use_grid: jax.Array  # the evidence grid's lead commits (``grid``)
    grid_margin: jax.Array  # its commit margin (0 where unused)
    confidence_ratio: jax.Array  # (S,) baselines
    support_ratio: jax.Array  # (S,)


jax.tree_util.register_dataclass(
    Lanes, data_fields=list(Lanes.__dataclass_fields__), meta_fields=[]
)


@dataclass(frozen=True)
class LaneSpec:
    """The static side of a set of lanes: their names, the core modes they need, the lane
    whose commits trigger the global search for rivals, the symmetry thresholds the maps
    must carry, and whether baselines are decided."""

    names: tuple[str, ...]  # one per output lane: ours lanes, then baselines
    sets: tuple[int, ...]  # the threshold set of each output lane
    modes: tuple[tuple[bool, int], ...]  # (use_gate, symmetry set) per core mode
    primary: int  # lane index; -1: no rival search
    min_iou: tuple[float, ...]  # symmetry thresholds, in set order
    n_sets: int  # threshold sets
    baselines: bool
    unique: bool = False  # some lane runs the uniqueness test
    grid: bool = False  # some lane keeps the evidence grid

    @property
    def searches(self) -> bool:
        """Some lane searches the plan for the path (rival search, uniqueness test, evidence
        grid): the buildings need their search fields."""
        return self.primary >= 0 or self.unique or self.grid

    @property
    def n_ours(self) -> int:
        return len(self.names) - (len(BASELINES) * self.n_sets if self.baselines else 0)


def make_lanes(params: DecisionParams | list[DecisionParams] | None = None,
          ours=("ours",), baselines: bool = False, primary: str | None = "ours",
          primary_set: int = 0) -> tuple[DecisionParams, Lanes, LaneSpec]:  # fmt: skip
    """Lanes for ``ours`` x threshold sets (+ the baselines per set).

    Args:
        params: one ``DecisionParams`` or a list of threshold sets that may differ only in
            ``KNOBS``.
        ours: names of ``OURS_VARIANTS``.
        baselines: decide the forced-choice baselines too.
        primary: the variant whose commits trigger the rival search (at ``primary_set``);
            None: no search.

    Returns:
        ``(p, lanes, spec)``: the shared parameters (knobs of the first set), the traced
        lanes (set-major: set 0's variants, set 1's, ...) and their static side.
    """
    sets = params if isinstance(params, list) else [params or DecisionParams()]
    check_sets(sets)
    bad = [n for n in ours if n not in OURS_VARIANTS]
    if bad:
        raise ValueError(f"lanes: unknown variants {bad}; known {list(OURS_VARIANTS)}")
    syms = sorted({OURS_VARIANTS[n][5] for n in ours} | {0})
    min_iou = tuple((0.8, STRICT_IOU)[q] for q in syms)
    modes = sorted({(OURS_VARIANTS[n][0], syms.index(OURS_VARIANTS[n][5])) for n in ours})
    modes = tuple(sorted(modes, key=lambda m: (not m[0], m[1])))
    cols, names, lane_sets = [], [], []
    for i, s in enumerate(sets):
        for n in ours:
            ug, up, uc, bm, dm, q, alpha, gm = OURS_VARIANTS[n]
            uu = alpha > 0
            bm = float(s.b_min) if bm < 0 else bm
            dm = float(s.delta_min) if dm < 0 else dm
            mode = modes.index((ug, syms.index(q)))
            thr = unique_threshold(n)
            cols.append((ug, up, uc, bm, dm, float(s.cert_margin), mode, uu, thr, gm > 0, gm))
            names.append(n)
            lane_sets.append(i)
    c = list(zip(*cols, strict=True))
    f32 = np.float32
    lanes_ = Lanes(
        use_gate=np.asarray(c[0], bool),
        use_probe=np.asarray(c[1], bool),
        use_cert=np.asarray(c[2], bool),
        b_min=np.asarray(c[3], f32),
        delta_min=np.asarray(c[4], f32),
        cert_margin=np.asarray(c[5], f32),
        mode=np.asarray(c[6], np.int32),
        use_unique=np.asarray(c[7], bool),
        unique_llr=np.asarray(c[8], f32),
        use_grid=np.asarray(c[9], bool),
        grid_margin=np.asarray(c[10], f32),
        confidence_ratio=np.asarray([float(s.confidence_ratio) for s in sets], f32),
        support_ratio=np.asarray([float(s.support_ratio) for s in sets], f32),
    )
    if baselines:
        names += [b for _ in sets for b in BASELINES]
        lane_sets += [i for i in range(len(sets)) for _ in BASELINES]
    lane = -1
    if primary is not None and primary in ours and OURS_VARIANTS[primary][2]:
        lane = primary_set * len(ours) + list(ours).index(primary)
    unique = any(OURS_VARIANTS[n][6] > 0 for n in ours)
    grid = any(OURS_VARIANTS[n][7] > 0 for n in ours)
    spec = LaneSpec(tuple(names), tuple(lane_sets), modes, lane, min_iou, len(sets), baselines,
                    unique, grid)  # fmt: skip
    return sets[0], lanes_, spec
