"""The robot's path: a scan sequence localized window by window against one floor plan.

The same pieces as the study and the benchmark: windows are cut by ``windows`` (causally, as
they complete: ``windows.Cutter``), and each window goes through ONE jitted step: the
front-end registers the submap (``frontend.registration.register``), the layer anchors its
candidates and decides (``decision.layer.update``). The layer's state stays on the device
between windows; per window one transfer goes in (the submap, the new keyframes, the
evidence sample) and one comes out (the decision). Ground truth never enters.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import windows as W
from mfcl_jax.decision import layer, rivals
from mfcl_jax.decision.history import Caps
from mfcl_jax.decision.lanes import ROBOT_POLICIES, early_threshold, make_lanes
from mfcl_jax.decision.maps import decision_maps
from mfcl_jax.decision.outcome import Decision
from mfcl_jax.decision.params import DecisionParams
from mfcl_jax.frontend import COMPILER_OPTIONS, FrontendParams, registration
from mfcl_jax.frontend.driver import FrontEnd
from mfcl_jax.robot import records, status
from mfcl_jax.robot.traced import Traced
from mfcl_jax.windows.arrays import (
    EVIDENCE_POINTS,
    SubmapBatch,
    bucket,
    end_sample,
    evidence_sample,
)

__all__ = ["LocalizeParams", "WindowResult", "Localizer", "localize"]

ROBOT_CAPS = Caps(windows=64, cands=32, traj=1024, step=64, evidence=EVIDENCE_POINTS)


@dataclass(frozen=True)
class LocalizeParams:
    """Settings of the localization path (defaults: the study's and the paper's).

    Attributes:
        window: how scans are cut into submaps (``d_s``, step, voxel, crop, capacity).
        frontend: front-end parameters (static; one compilation per value).
        decision: decision thresholds (``None``: paper defaults).
        caps: the layer's capacities (``decision.history``: what a long run keeps).
        policy: the lane decided: ``ours`` (commit on the count of agreeing windows) or a
            uniqueness lane ``ours_unique*`` (also commit as soon as the whole path is unique
            at its error rate, ``decision.lanes.UNIQUE_LANES``; ``mfcl localize
            --early-commit``).
    """

    window: W.WindowParams = field(default_factory=W.WindowParams)
    frontend: FrontendParams = field(default_factory=FrontendParams)
    decision: DecisionParams | None = None
    caps: Caps = ROBOT_CAPS
    policy: str = "ours"

    def __post_init__(self):
        if self.policy not in ROBOT_POLICIES:
            raise ValueError(f"LocalizeParams: policy={self.policy!r}, expected one of "
                             f"{list(ROBOT_POLICIES)}")  # fmt: skip

    @property
    def unique_llr(self) -> float | None:
        """``log(1 / alpha)`` a uniqueness lane commits at; None for ``ours``."""
        return early_threshold(self.policy) or None

    @property
    def d_s(self) -> float:
        return self.window.d_s

    def with_d_s(self, d_s: float) -> LocalizeParams:
        return replace(self, window=replace(self.window, d_s=float(d_s)))


@dataclass(frozen=True)
class WindowResult:
    """One window: where it lies in the input, what the front-end saw, the decision.

    Attributes:
        k: 1-based window count (over the whole recording).
        decision: the ``Decision`` of the window (host scalars).
        first, last: indices of the window's first and last scan in the input sequence.
        t: time of the last scan (the decision's time).
        X: ``(3,)`` pose of the last scan in the layer's odometry (LiDAR-refined where
            enabled), ``^L T_{S_k}``.
        n_points: points in the submap after thinning.
        voxel: voxel edge used (m); larger than the configured one when re-thinned.
        n_candidates: valid candidates from the front-end.
        frontend_reason: ``batch.REASONS`` key (0 when candidates exist).
        rethinned: the window was thinned with a coarser voxel to fit the capacity.
        X_input: ``(3,)`` the input odometry's pose at the same time.
        segment: the odometry segment of the window (0, plus one after every jump).
        points: ``(n, 2)`` the window's submap points in its frame ``S_k`` (``X`` places them
            in the odometry frame, ``T* X`` in the plan).
        unique_llr: the uniqueness lane's threshold ``log(1 / alpha)`` (None for ``ours``).
        storeys: the plan's ``floorplan.storeys.Storeys`` (None for one storey).
    """

    k: int
    decision: object
    first: int
    last: int
    t: float
    X: np.ndarray
    n_points: int
    voxel: float
    n_candidates: int
    frontend_reason: int
    rethinned: bool
    X_input: np.ndarray
    segment: int = 0
    points: np.ndarray | None = None
    unique_llr: float | None = None
    storeys: object = None

    def record(self, offset=(0.0, 0.0)) -> dict:
        """The decisions-file line (``records.record_of``; ``offset``: plan = local + offset), with
        the window's ``k`` over the recording and its odometry ``segment``."""
        return records.record_of(self.decision, self.k, self.t, self.X, self.X_input, offset,
                         self.segment, self.unique_llr, self.storeys)  # fmt: skip

    def status(self, offset=(0.0, 0.0)) -> str:
        """One human-readable status line (``status.status_line``)."""
        thin = f" rethinned voxel={self.voxel:.2f}" if self.rethinned else ""
        detail = f"pts={self.n_points}{thin} cands={self.n_candidates}"
        return status.status_line(self.record(offset), detail)


def _step(world, memory, sub, feats, X, traj, traj_mask, start, ev, fe_params):
    """register -> anchor -> decide, for one window (the robot's whole step)."""
    c = registration.register(sub, feats, fe_params)
    f32 = jnp.float32
    evidence = layer.WindowEvidence(
        Y=c.pose[0], score=c.score[0], mask=c.mask[0], X=X, traj=traj, traj_mask=traj_mask,
        head=jnp.zeros((0, 3), f32), head_mask=jnp.zeros(0, bool), start=start,
        ev_points=ev[0], ev_origins=ev[1], ev_mask=ev[2], valid=jnp.bool_(True),
        last=jnp.bool_(False), restart=jnp.bool_(False), end_points=ev[3], end_mask=ev[4],
    )  # fmt: skip
    state, dec = layer.update(layer.join(world, memory), evidence)
    return layer.split(state)[1], jax.tree.map(lambda a: a[0], dec), c.reason[0], jnp.sum(c.mask[0])


def _step_like(world, memory, *_):
    """The structure of ``_step``'s output (``Traced`` reads a kept program back untraced)."""
    return memory, Decision(**dict.fromkeys(Decision.__dataclass_fields__, 0)), 0, 0


def _advance(world, memory, traj, traj_mask):
    return layer.split(layer.advance(layer.join(world, memory), traj, traj_mask))[1]


class Localizer:
    """Floor-plan state (features, gate maps, the compiled step) built once, then any number
    of sequences localized against it.

    Args:
        floorplan: the ``Floorplan`` (frame B).
        params: ``LocalizeParams``.
    """

    def __init__(self, floorplan, params: LocalizeParams | None = None):
        self.floorplan = floorplan
        self.params = params or LocalizeParams()
        fe = FrontEnd([floorplan], self.params.frontend, chunk=1)
        self._feats = jax.tree.map(jnp.asarray, fe.features(0))
        policy = self.params.policy
        p, lanes, spec = make_lanes(self.params.decision, (policy,), primary=policy)
        maps = jax.tree.map(jnp.asarray, decision_maps(floorplan, min_iou=spec.min_iou))
        fields = jax.tree.map(jnp.asarray, rivals.rival_fields(floorplan))
        n_img = rivals.image_size([floorplan]) if spec.searches else 0
        self._init = (maps, p.as_arrays(), self.params.caps, jax.tree.map(jnp.asarray, lanes),
                      spec, fields, n_img)  # fmt: skip
        folder = jax.config.jax_compilation_cache_dir
        fe_params = self.params.frontend
        self._step = Traced(partial(_step, fe_params=fe_params), "step", folder,
                            static=repr(fe_params), out_like=_step_like, donate_argnums=(1,),
                            compiler_options=COMPILER_OPTIONS)  # fmt: skip
        self._advance = jax.jit(_advance, donate_argnums=(1,))
        self._capacity = bucket(self.params.window.capacity, 256)

    @property
    def n_programs(self) -> int:
        """Programs of the step so far: 1 when every window had the prepared shape."""
        return self._step.n_programs

    def estimate(self, seq) -> int:
        """The number of windows of ``seq`` by its input odometry (a progress total)."""
        return W.Cutter(self.params.window).estimate(seq)

    def run(self, seq) -> Iterator[WindowResult]:
        """Streams the windows of ``seq``; yields one ``WindowResult`` per window, each as
        soon as its keyframes are refined and it is decided."""
        return self.follow([seq], prepare=self.estimate(seq) > 0, live=False)

    def follow(self, prefixes, prepare: bool = True, live: bool = True) -> Iterator[WindowResult]:
        """Streams the windows of a recording that grows (the live path).

        Args:
            prefixes: ever longer ``ScanSequence``s of one recording, each extending the one
                before; every window complete in a prefix and not yet seen is decided.
                Windows are causal, so the results are ``run``'s on the last prefix.
            prepare: compile the step in the background from the start (``_prepare``); off
                where no window is expected, so that nothing is compiled for nothing.
            live: the prefixes grow a few scans at a time (``windows.Cutter``'s ``live``:
                the LiDAR odometry in small chunks; the same windows).
        """
        if prepare:
            self._prepare()
        cutter = W.Cutter(self.params.window, live=live)
        world, memory, prev_end, seg, base, k = None, None, -1, None, 0, 0
        step = self.params.caps.step
        for seq in prefixes:
            for w in cutter.feed(seq):
                k += 1
                j0, j1 = (int(v) for v in w.bounds[0])
                if w.segments[j0] != seg:
                    # A new odometry segment (a restart): poses before and after are in
                    # incommensurable frames, so the layer starts over.
                    seg = w.segments[j0]
                    world, memory = layer.split(layer.init(*self._init))
                    base = int(np.flatnonzero(w.segments == seg)[0])
                    prev_end = base - 1
                traj = np.asarray(w.odometry[prev_end + 1 : j1 + 1], np.float32)
                while len(traj) > step:  # keyframes beyond one update's capacity
                    memory = self._advance(world, memory, traj[:step], np.ones(step, bool))
                    traj = traj[step:]
                tr = np.zeros((step, 3), np.float32)
                tm = np.arange(step) < len(traj)
                tr[: len(traj)] = traj
                prev_end = j1
                memory, dec, reason, n_cand = self._step(
                    world, memory, *self._inputs(w.points[0], w.origins[0], w.last_points[0],
                                                 w.X[0], w.t[0], tr, tm, j0 - base),
                )  # fmt: skip
                yield WindowResult(
                    k=k, decision=jax.tree.map(np.asarray, dec), first=int(w.keyframes[j0]),
                    last=int(w.keyframes[j1]), t=float(w.t[0]), X=np.asarray(w.X[0]),
                    n_points=len(w.points[0]), voxel=float(w.voxel[0]), n_candidates=int(n_cand),
                    frontend_reason=int(reason), rethinned=bool(W.rethinned(w)[0]),
                    X_input=np.asarray(w.X_input[0]), segment=int(seg), points=w.points[0],
                    unique_llr=self.params.unique_llr, storeys=self.floorplan.storeys,
                )  # fmt: skip

    def _inputs(self, pts, org, last, X, t, traj, traj_mask, start) -> tuple:
        """The step's inputs after ``(world, memory)``: the window's points and origins
        ``(n, 2)``, its last scan ``last (m, 2)`` (``Windows.last_points``), its pose
        ``X (3,)`` and time, the keyframes it adds (``Caps.step``) and its first keyframe in
        the segment."""
        cap = self._capacity
        n = len(pts)
        points = np.zeros((1, cap, 2), np.float32)
        origins = np.zeros((1, cap, 2), np.float32)
        mask = np.zeros((1, cap), bool)
        points[0, :n], origins[0, :n], mask[0, :n] = pts, org, True
        X = np.asarray(X, np.float32)
        sub = SubmapBatch(points, origins, mask, X[None], np.zeros(1, np.int32),
                          np.zeros(1, np.int32), np.asarray([t], np.float64),
                          np.zeros(1, np.int32))  # fmt: skip
        return (registration.sanitize_submaps(sub), self._feats, X,
                np.asarray(traj, np.float32), np.asarray(traj_mask, bool), np.int32(start),
                (*evidence_sample(pts, org), *end_sample(last)))  # fmt: skip

    def _prepare(self) -> None:
        """The step traced and compiled in the background (``Traced.prepare``) for inputs
        shaped like every window's, while the odometry runs over the first metres."""
        if self._step.n_programs:
            return
        world, memory = layer.split(layer.init(*self._init))
        z = np.zeros((0, 2), np.float32)
        step = self.params.caps.step
        self._step.prepare(world, memory, *self._inputs(z, z, z, np.zeros(3), 0.0,
                                                        np.zeros((step, 3)), np.zeros(step),
                                                        0))  # fmt: skip


def localize(floorplan, seq, params: LocalizeParams | None = None) -> list:
    """All ``WindowResult``s of one sequence (convenience wrapper of ``Localizer.run``)."""
    return list(Localizer(floorplan, params).run(seq))
