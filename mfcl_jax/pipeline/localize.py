"""Localize a scan sequence against a floor plan, one decision per submap window.

The path a robot would run online, on the host's stream of scans:

1. keyframes (``sequence.keyframes``) and the simulator's sliding windows over odometric
   travelled distance (``sim.submaps.window_bounds``), so windows on a dataset written by the
   simulator are exactly the simulator's windows;
2. each window's submap (``sim.submaps.build_submap``: scans moved into the frame of its last
   scan by odometry, voxel-thinned, cropped), padded on the host to ONE fixed point capacity
   so the jitted front-end compiles once per run of the program. A submap over capacity is
   re-thinned with a coarser voxel (x1.5 until it fits) and the window reports the voxel it
   used; nothing is truncated;
3. the jitted front-end (``frontend.make_register``) gives candidates ``Y_ij``;
4. ``decision.SelectiveInitializer.update`` turns them into the decision at this prefix.

Ground truth never enters: the localizer sees a floor plan and a ``ScanSequence`` only.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import jax
import numpy as np

from mfcl_jax.batch import SubmapBatch, bucket
from mfcl_jax.decision import DecisionParams, SelectiveInitializer, gate_maps
from mfcl_jax.decision.stream import Decision
from mfcl_jax.frontend import FrontendParams, build_features, make_register
from mfcl_jax.io.errors import DataError
from mfcl_jax.sim.submaps import SubmapParams, build_submap, window_bounds
from mfcl_jax.sim.trajectory import travelled
from mfcl_jax.sources.sequence import ScanSequence, keyframes

__all__ = ["LocalizeParams", "WindowResult", "Localizer", "localize"]


@dataclass(frozen=True)
class LocalizeParams:
    """Settings of the localization path (defaults: the simulator's and the paper's).

    Attributes:
        d_s: window length (m).
        submap: step, voxel, crop radius of the windows.
        frontend: front-end parameters (static; one compilation per value).
        decision: decision thresholds (``None``: paper defaults).
        capacity: fixed point capacity of a submap (a power of two keeps the front-end's
            strided subsamples regular).
        keyframe_spacing, keyframe_turn_deg: keyframe thresholds (``sequence.keyframes``).
        max_rethin: how many times an over-capacity submap may be re-thinned (voxel x1.5 each)
            before it is an error.
    """

    d_s: float = 6.0
    submap: SubmapParams = field(default_factory=SubmapParams)
    frontend: FrontendParams = field(default_factory=FrontendParams)
    decision: DecisionParams | None = None
    capacity: int = 4096
    keyframe_spacing: float = 0.20
    keyframe_turn_deg: float = 20.0
    max_rethin: int = 6

    def __post_init__(self):
        if not self.d_s > 0:
            raise ValueError(f"LocalizeParams: d_s must be > 0, got d_s={self.d_s!r}")
        if self.capacity < 64:
            raise ValueError(f"LocalizeParams: capacity must be >= 64, got {self.capacity!r}")


@dataclass(frozen=True)
class WindowResult:
    """One window: where it lies in the input, what the front-end saw, the decision.

    Attributes:
        decision: the ``Decision`` at this prefix (``decision.k`` is the 1-based window).
        first, last: indices of the window's first and last scan in the input sequence.
        t: time of the last scan (the decision's time).
        X: ``(3,)`` odometry pose of the last scan, ``^L T_{S_k}``.
        n_points: points in the submap after thinning.
        voxel: voxel edge used (m); larger than the configured one when re-thinned.
        n_candidates: valid candidates from the front-end.
        frontend_reason: ``batch.REASONS`` key (0 when candidates exist).
    """

    decision: Decision
    first: int
    last: int
    t: float
    X: np.ndarray
    n_points: int
    voxel: float
    n_candidates: int
    frontend_reason: int
    rethinned: bool = False

    def status(self) -> str:
        """One human-readable status line."""
        d = self.decision
        g = d.diagnostics
        if d.state == "COMMIT":
            x, y, yaw = d.anchor
            anchor = f"({x:.2f}, {y:.2f}, {np.rad2deg(yaw):.1f} deg)"
        else:
            anchor = "-"
        tau = "-" if d.tau is None else f"({d.tau[0]:.2f}, {d.tau[1]:.2f})"
        kind = f" {d.kind}" if d.kind else ""
        why = f" [{g.get('reason')}]" if g.get("reason") else ""
        thin = f" rethinned voxel={self.voxel:.2f}" if self.rethinned else ""
        return (
            f"k={d.k:3d} t={self.t:10.2f} {d.state:9s}{kind} anchor={anchor} "
            f"B1={g['B1']} B2={g['B2']} margin={g['margin']} tau={tau} "
            f"pts={self.n_points}{thin} cands={self.n_candidates}{why}"
        )


class Localizer:
    """Floor-plan state (features, gate maps, the jitted front-end) built once, then any
    number of sequences localized against it.

    Args:
        floorplan: the ``Floorplan`` (frame B).
        params: ``LocalizeParams``.
    """

    def __init__(self, floorplan, params: LocalizeParams | None = None):
        self.floorplan = floorplan
        self.params = params or LocalizeParams()
        self._feats = build_features(floorplan, self.params.frontend)
        self._maps = _gate_maps(floorplan)
        self._register = make_register(self.params.frontend)

    def windows(self, seq: ScanSequence) -> tuple[np.ndarray, np.ndarray]:
        """Keyframe indices ``(M,)`` and window bounds ``(K, 2)`` (inclusive, into keyframes)."""
        p = self.params
        kf = keyframes(seq.odometry, p.keyframe_spacing, p.keyframe_turn_deg)
        bounds = window_bounds(travelled(seq.odometry[kf]), p.d_s, p.submap.step)
        return kf, bounds

    def submap(self, seq: ScanSequence, kf: np.ndarray, j0: int, j1: int):
        """Points and ray origins ``(n, 2)`` of one window, and the voxel used."""
        idx = kf[j0 : j1 + 1]
        width = max(1, max(len(seq.scans[i]) for i in idx))
        pts = np.full((len(idx), width, 2), np.nan)
        for r, i in enumerate(idx):
            s = np.asarray(seq.scans[i], np.float64).reshape(-1, 2)
            pts[r, : len(s)] = s
        sp = self.params.submap
        for _ in range(self.params.max_rethin + 1):
            p, o = build_submap(pts, seq.odometry[idx], 0, len(idx) - 1, sp)
            if len(p) <= self.params.capacity:
                return p, o, sp.voxel
            sp = replace(sp, voxel=sp.voxel * 1.5)
        raise DataError(
            f"{seq.source}: window of scans {idx[0]}..{idx[-1]} keeps {len(p)} points at "
            f"voxel {sp.voxel / 1.5:.2f} m, over the capacity {self.params.capacity}"
        )

    def _batch(self, p, o, X, k, t) -> SubmapBatch:
        cap = self.params.capacity
        pts = np.zeros((1, cap, 2), np.float32)
        org = np.zeros((1, cap, 2), np.float32)
        mask = np.zeros((1, cap), bool)
        pts[0, : len(p)], org[0, : len(o)], mask[0, : len(p)] = p, o, True
        return SubmapBatch(
            points=pts,
            origins=org,
            mask=mask,
            X=np.asarray(X, np.float32)[None],
            run=np.zeros(1, np.int32),
            window=np.asarray([k], np.int32),
            t=np.asarray([t], np.float32),
            n_dropped=np.zeros(1, np.int32),
        )

    def run(self, seq: ScanSequence, variant: str = "ours") -> Iterator[WindowResult]:
        """Streams the windows of ``seq``; yields one ``WindowResult`` per window."""
        kf, bounds = self.windows(seq)
        # Buffers sized up front (powers of two): one decision compilation per size bucket.
        init = SelectiveInitializer(
            self._maps,
            self.params.decision,
            variant=variant,
            k_cap=bucket(len(bounds), 8),
            j_cap=self.params.frontend.J,
            t_cap=bucket(len(kf), 256),
        )
        prev_end = -1
        for k, (j0, j1) in enumerate(bounds):
            j0, j1 = int(j0), int(j1)
            i1 = int(kf[j1])
            p, o, voxel = self.submap(seq, kf, j0, j1)
            X = seq.odometry[i1]
            t = float(seq.times[i1])
            cand = jax.tree.map(np.asarray, self._register(self._batch(p, o, X, k, t), self._feats))
            m = cand.mask[0]
            traj = seq.odometry[kf[prev_end + 1 : j1 + 1]]
            prev_end = j1
            dec = init.update(cand.pose[0][m], cand.score[0][m], X, traj, t=t)
            yield WindowResult(
                decision=dec,
                first=int(kf[j0]),
                last=i1,
                t=t,
                X=np.asarray(X),
                n_points=len(p),
                voxel=voxel,
                n_candidates=int(m.sum()),
                frontend_reason=int(cand.reason[0]),
                rethinned=voxel > self.params.submap.voxel,
            )

    def n_windows(self, seq: ScanSequence) -> int:
        return len(self.windows(seq)[1])


def _gate_maps(fp):
    """``gate_maps`` sized to the building (it grows its offset capacity itself)."""
    return gate_maps(fp)


def localize(floorplan, seq: ScanSequence, params: LocalizeParams | None = None) -> list:
    """All ``WindowResult``s of one sequence (convenience wrapper of ``Localizer.run``)."""
    return list(Localizer(floorplan, params).run(seq))
