"""Streaming decisions for a robot: one ``update`` per submap window.

The initializer keeps padded host buffers (windows, candidates, trajectory samples) whose
capacities double when full, so the jitted single-prefix decision recompiles only
``O(log n)`` times over a run. Each update evaluates exactly the batch path's kernel
(``state.decide_prefix``) on the newest prefix, with gate consistencies computed directly at
that prefix (bit-identical to the batch path's cumulative table), then one step of the commit
machine (``machine.step``, whose memory the initializer keeps), so the stream reproduces the
batch states.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.batch import EVIDENCE_POINTS, evidence_sample
from mfcl_jax.decision import gate as gate_mod
from mfcl_jax.decision import lattice, machine
from mfcl_jax.decision.anchors import sanitize
from mfcl_jax.decision.evaluate import NO_RIVAL
from mfcl_jax.decision.maps import DecisionMaps, decision_maps
from mfcl_jax.decision.policies import OURS_VARIANTS
from mfcl_jax.decision.rivals import (
    DEFAULT_RIVALS,
    RIVAL_SLOTS,
    RivalParams,
    rival_fields,
    search_into,
)
from mfcl_jax.decision.state import COMMIT, REASONS, STATE_NAMES, DecisionParams, decide_prefix
from mfcl_jax.frontend.path_search import PlanFields

__all__ = ["Decision", "SelectiveInitializer"]


@dataclass(frozen=True)
class Decision:
    """The decision after one window (host values).

    Attributes:
        k: 1-based window count; t: time stamp given to ``update`` (or None).
        state: "COMMIT" | "AMBIGUOUS" | "DEFER".
        anchor: ``(x, y, yaw)`` of T* (the commit anchor when COMMIT).
        kind: None | "translation" | "multimodal" | "rotation" | "mirror".
        tau: ``(tx, ty)`` or None.
        diagnostics: B1, B2, margin, spread, rooms, c_winner, winner_gate, probe_alias,
            probe_c, n_champions, n_groups, reason, n_rejected, alias_motion: the
            building's self-motion ``g = (x, y, yaw)`` carrying T* onto its rotational alias
            ``g T*`` when the kind is rotation (None otherwise), and competitor: the anchor
            ``(x, y, yaw)`` of the strongest competing explanation when AMBIGUOUS
            (``Decisions.competitor``; None otherwise or when there is none).
    """

    k: int
    t: float | None
    state: str
    anchor: tuple[float, float, float]
    kind: str | None
    tau: tuple[float, float] | None
    diagnostics: dict = field(default_factory=dict)

    def to_json(self) -> str:
        """One line of the decisions JSON-lines format (anchor only when COMMIT)."""
        d = self.diagnostics
        anchor = None
        if self.state == "COMMIT":
            x, y, yaw = self.anchor
            anchor = {"x": x, "y": y, "yaw_deg": float(np.rad2deg(yaw))}
        return json.dumps(
            {
                "k": self.k,
                "t": self.t,
                "state": self.state,
                "anchor": anchor,
                "symmetry": self.kind,
                "tau": None if self.tau is None else list(self.tau),
                "B1": d["B1"],
                "B2": d["B2"],
                "margin": d["margin"],
            }
        )


@partial(jax.jit, static_argnames=("n_cap",))
def _decide_latest(
    H, score, mask, traj, traj_mask, bounds, X, evidence, k, maps, p, flags, held, rivals,
    n_cap=3,
):  # fmt: skip
    cons = gate_mod.consistency_at(maps, H, traj, traj_mask, bounds[1][k])
    ug, up, uc, bm, dm = flags
    bm = jnp.where(bm < 0, p.b_min, bm)
    dm = jnp.where(dm < 0, p.delta_min, dm)
    raw = decide_prefix(
        k, H, score, mask, cons, traj, traj_mask, bounds, X, evidence, maps, p,
        (ug, up, uc, bm, dm), n_cap, rivals,
    )  # fmt: skip
    newest = (H[k], score[k], mask[k], X[k])
    return machine.step(held, raw, newest, p, ug)


def _grow(a: np.ndarray, axis: int, need: int, fill) -> np.ndarray:
    cap = a.shape[axis]
    if need <= cap:
        return a
    while cap < need:
        cap *= 2
    pad = [(0, 0)] * a.ndim
    pad[axis] = (0, cap - a.shape[axis])
    return np.pad(a, pad, constant_values=fill)


class SelectiveInitializer:
    """Streaming selective initializer (our policy or one of its variants).

    Args:
        source: ``Floorplan``, ``Rasters`` or ready ``DecisionMaps``.
        params: scalar ``DecisionParams``.
        variant: a key of ``OURS_VARIANTS``.
        k_cap, j_cap, t_cap: initial buffer capacities (they double when exceeded).
        rivals: settings of the global search for rivals of a commit (``rivals``), run where
            the layer is about to commit, as the batch driver does; None: no search.
        plan: what the search reads when ``source`` is ready ``DecisionMaps``: the
            ``Floorplan``, its ``Rasters`` or ready ``path_search.PlanFields``.
    """

    def __init__(
        self,
        source,
        params: DecisionParams | None = None,
        variant: str = "ours",
        k_cap: int = 8,
        j_cap: int = 16,
        t_cap: int = 256,
        n_cap: int = 3,
        rivals: RivalParams | None = DEFAULT_RIVALS,
        plan=None,
    ):
        if variant not in OURS_VARIANTS:
            raise ValueError(
                f"SelectiveInitializer: unknown {variant=}; known {list(OURS_VARIANTS)}"
            )
        ug, up, uc, bm, dm = OURS_VARIANTS[variant]
        self._rival_params = rivals if uc else None
        plan = source if plan is None else plan
        if self._rival_params is not None and isinstance(plan, DecisionMaps):
            raise ValueError(
                "SelectiveInitializer: the rival search reads the floor plan; with ready "
                "DecisionMaps pass plan= (a Floorplan, Rasters or PlanFields), or rivals=None"
            )
        self._fields = None
        if self._rival_params is not None:
            self._fields = plan if isinstance(plan, PlanFields) else rival_fields(plan, rivals)
            self._fields = jax.tree.map(jnp.asarray, self._fields)
        self._rivals = np.zeros((RIVAL_SLOTS, 3), np.float32)
        self._rivals_k = np.full(RIVAL_SLOTS, NO_RIVAL, np.int32)
        self._searches = 0
        self._was_committed = False
        maps = source if isinstance(source, DecisionMaps) else decision_maps(source)
        self._maps = jax.tree.map(jnp.asarray, maps)
        self._params = (params or DecisionParams()).as_arrays()
        self._flags = (
            jnp.bool_(ug), jnp.bool_(up), jnp.bool_(uc), jnp.float32(bm), jnp.float32(dm)
        )  # fmt: skip
        self._certifies = bool(uc)
        self._n_cap = n_cap
        self.H = np.zeros((k_cap, j_cap, 3), np.float32)
        self.score = np.zeros((k_cap, j_cap), np.float32)
        self.mask = np.zeros((k_cap, j_cap), bool)
        self.traj = np.zeros((t_cap, 3), np.float32)
        self.traj_mask = np.zeros(t_cap, bool)
        self.window_start = np.zeros(k_cap, np.int32)
        self.window_end = np.zeros(k_cap, np.int32)
        self.X = np.zeros((k_cap, 3), np.float32)
        self.ev_points = np.zeros((k_cap, EVIDENCE_POINTS, 2), np.float32)
        self.ev_origins = np.zeros((k_cap, EVIDENCE_POINTS, 2), np.float32)
        self.ev_mask = np.zeros((k_cap, EVIDENCE_POINTS), bool)
        self.k = 0
        self.t = 0
        self.n_rejected = 0
        self._held = machine.initial()

    def update(
        self,
        candidate_poses,
        scores,
        X_i,
        trajectory_poses_since_last,
        t: float | None = None,
        window_start: int | None = None,
        evidence=None,
    ) -> Decision:
        """Adds one window and returns the decision at this prefix.

        Args:
            candidate_poses: ``(J, 3)`` ``Y_ij = ^B T_{S_i}`` (may be empty; NaN rows rejected).
            scores: ``(J,)``.
            X_i: ``(3,)`` ``^L T_{S_i}``.
            trajectory_poses_since_last: ``(T_i, 3)`` odometry poses since the last update, the
                last one being this window's last scan.
            t: optional time stamp echoed in the decision.
            window_start: index (into all trajectory samples given so far, from 0) of this
                window's first scan, so overlapping windows count as one piece of evidence
                (``consensus.disjoint_count``); default: the first sample of this update.
            evidence: ``(points (n, 2), origins (n, 2))`` of the window's submap in its frame
                (the certification re-scores them); required by certifying variants.
        """
        Y = np.asarray(candidate_poses, np.float32).reshape(-1, 3)
        s = np.asarray(scores, np.float32).reshape(-1)
        X = np.asarray(X_i, np.float32).reshape(-1)
        tr = np.asarray(trajectory_poses_since_last, np.float32).reshape(-1, 3)
        if s.shape[0] != Y.shape[0]:
            raise ValueError(f"update: {Y.shape[0]} candidate poses but {s.shape[0]} scores")
        if X.shape != (3,) or not np.all(np.isfinite(X)):
            raise ValueError(f"update: X_i must be a finite (3,) pose, got {X.tolist()}")
        if not np.all(np.isfinite(tr)):
            raise ValueError("update: trajectory_poses_since_last holds non-finite poses")
        if self.t + tr.shape[0] == 0:
            raise ValueError("update: no trajectory sample yet (T_i = 0 on the first window)")
        if evidence is None and self._certifies:
            raise ValueError("update: this variant certifies its commits; pass evidence=")
        j = Y.shape[0]
        self.H = _grow(_grow(self.H, 0, self.k + 1, 0.0), 1, j, 0.0)
        self.score = _grow(_grow(self.score, 0, self.k + 1, 0.0), 1, j, 0.0)
        self.mask = _grow(_grow(self.mask, 0, self.k + 1, False), 1, j, False)
        self.window_start = _grow(self.window_start, 0, self.k + 1, 0)
        self.window_end = _grow(self.window_end, 0, self.k + 1, 0)
        self.X = _grow(self.X, 0, self.k + 1, 0.0)
        self.ev_points = _grow(self.ev_points, 0, self.k + 1, 0.0)
        self.ev_origins = _grow(self.ev_origins, 0, self.k + 1, 0.0)
        self.ev_mask = _grow(self.ev_mask, 0, self.k + 1, False)
        self.traj = _grow(self.traj, 0, self.t + tr.shape[0], 0.0)
        self.traj_mask = _grow(self.traj_mask, 0, self.t + tr.shape[0], False)
        # Anchors at the buffer's static width (padded rows sliced off): the number of
        # candidates changes from window to window, and eager ops on a new shape compile anew
        # (measured: 1.2-1.6 s stalls at the first windows of ``benchmarks/stream.py``).
        jc = self.H.shape[1]
        y_pad, s_pad, m_pad = (
            np.zeros((jc, 3), np.float32),
            np.zeros(jc, np.float32),
            np.arange(jc) < j,
        )
        y_pad[:j], s_pad[:j] = Y, s
        H = se2.anchor(y_pad, X[None])
        H, s, m, bad = (np.asarray(a) for a in sanitize(H, s_pad, m_pad))
        H, s, m = H[:j], s[:j], m[:j]
        self.n_rejected += int(bad)
        self.H[self.k, :j], self.score[self.k, :j], self.mask[self.k, :j] = H, s, m
        self.traj[self.t : self.t + tr.shape[0]] = tr
        self.traj_mask[self.t : self.t + tr.shape[0]] = True
        self.t += tr.shape[0]
        self.window_end[self.k] = self.t - 1
        first_new = self.t - tr.shape[0]
        self.window_start[self.k] = first_new if window_start is None else int(window_start)
        self.X[self.k] = X
        if evidence is not None:
            pts, org = (np.asarray(a, np.float64).reshape(-1, 2) for a in evidence)
            sample = evidence_sample(pts, org)
            self.ev_points[self.k], self.ev_origins[self.k], self.ev_mask[self.k] = sample
        self.k += 1
        held, d = self._decide()
        entering = int(d.state) == COMMIT and not self._was_committed
        rp = self._rival_params
        if entering and rp is not None and self._searches < rp.max_searches:
            # about to commit: search the whole path for rivals, then decide this prefix again
            ev = (self.ev_points, self.ev_origins, self.ev_mask)
            search_into(self._rivals, self._rivals_k, self._searches, ev, self.X, self.k - 1,
                        self._fields, rp)  # fmt: skip
            self._searches += 1
            held, d = self._decide()
        self._held = held
        self._was_committed = int(d.state) == COMMIT
        return self._report(d, t)

    @property
    def searches(self) -> int:
        """Rival searches run so far (``rivals``: one where the layer was about to commit)."""
        return self._searches

    def _decide(self):
        held, d = _decide_latest(
            self.H,
            self.score,
            self.mask,
            self.traj,
            self.traj_mask,
            (self.window_start, self.window_end),
            self.X,
            (self.ev_points, self.ev_origins, self.ev_mask),
            jnp.int32(self.k - 1),
            self._maps,
            self._params,
            self._flags,
            self._held,
            # no rival slots to score before the first search (masked slots decide nothing;
            # the kernel with them compiles once, when a search has found rivals)
            (self._rivals, self._rivals_k) if self._searches else None,
            n_cap=self._n_cap,
        )
        return held, jax.tree.map(np.asarray, d)

    def _report(self, d, t) -> Decision:
        kind = lattice.KIND_NAMES[int(d.kind)]
        return Decision(
            k=self.k,
            t=t,
            state=STATE_NAMES[int(d.state)],
            anchor=tuple(float(v) for v in d.anchor),
            kind=kind,
            tau=tuple(float(v) for v in d.tau) if kind == "translation" else None,
            diagnostics={
                "B1": int(d.b1),
                "B2": int(d.b2),
                "margin": int(d.margin),
                "spread": float(d.spread),
                "rooms": int(d.rooms),
                "c_winner": float(d.c_winner),
                "winner_gate": bool(d.winner_gate),
                "probe_alias": bool(d.probe_alias),
                "probe_c": float(d.probe_c),
                "n_champions": int(d.n_champions),
                "n_groups": int(d.n_groups),
                "reason": REASONS[int(d.reason)],
                "n_rejected": self.n_rejected,
                "alias_motion": (
                    tuple(float(v) for v in d.alias_motion) if kind == "rotation" else None
                ),
                "competitor": (
                    tuple(float(v) for v in d.competitor) if bool(d.has_competitor) else None
                ),
            },
        )
