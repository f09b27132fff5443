"""The robot's path: a scan sequence localized window by window against one floor plan.

The same pieces as the study and the benchmark: windows are cut by ``windows`` (causally: a
window's bounds depend only on the scans up to its end, so the stream emits exactly the batch
windows), registered by the one front-end driver (``frontend.driver.FrontEnd``, one submap per
call) and decided by the streaming decision driver (``decision.stream``), which evaluates the
batch path's kernel at the newest prefix. Ground truth never enters.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from mfcl_jax import status
from mfcl_jax import windows as W
from mfcl_jax.batch import bucket
from mfcl_jax.decision import DecisionParams, SelectiveInitializer, decision_maps
from mfcl_jax.decision.rivals import rival_fields
from mfcl_jax.decision.stream import Decision
from mfcl_jax.frontend import FrontendParams
from mfcl_jax.frontend.driver import FrontEnd
from mfcl_jax.scanmatch import Odometer

__all__ = ["LocalizeParams", "WindowResult", "Localizer", "localize"]


@dataclass(frozen=True)
class LocalizeParams:
    """Settings of the localization path (defaults: the study's and the paper's).

    Attributes:
        window: how scans are cut into submaps (``d_s``, step, voxel, crop, capacity).
        frontend: front-end parameters (static; one compilation per value).
        decision: decision thresholds (``None``: paper defaults).
    """

    window: W.WindowParams = field(default_factory=W.WindowParams)
    frontend: FrontendParams = field(default_factory=FrontendParams)
    decision: DecisionParams | None = None

    @property
    def d_s(self) -> float:
        return self.window.d_s

    def with_d_s(self, d_s: float) -> LocalizeParams:
        return replace(self, window=replace(self.window, d_s=float(d_s)))


@dataclass(frozen=True)
class WindowResult:
    """One window: where it lies in the input, what the front-end saw, the decision.

    Attributes:
        decision: the ``Decision`` at this prefix (``decision.k`` is the 1-based window).
        first, last: indices of the window's first and last scan in the input sequence.
        t: time of the last scan (the decision's time).
        X: ``(3,)`` pose of the last scan in the layer's odometry (LiDAR-refined where
            enabled), ``^L T_{S_k}``.
        n_points: points in the submap after thinning.
        voxel: voxel edge used (m); larger than the configured one when re-thinned.
        n_candidates: valid candidates from the front-end.
        frontend_reason: ``batch.REASONS`` key (0 when candidates exist).
        rethinned: the window was thinned with a coarser voxel to fit the capacity.
        X_input: ``(3,)`` the input odometry's pose at the same time (default ``X``).
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
    X_input: np.ndarray | None = None

    def record(self, offset=(0.0, 0.0)) -> dict:
        """The decisions-file line: the decision with the robot's pose ``T* X_k`` and the
        reason (``status.record``; ``offset``: plan = local + offset)."""
        dec = self.decision
        d = json.loads(dec.to_json())
        reason = dec.diagnostics.get("reason", "")
        rival = dec.diagnostics.get("competitor")
        return status.record(d, self.X, reason, offset, self.X_input, dec.anchor, rival)

    def status(self, offset=(0.0, 0.0)) -> str:
        """One human-readable status line (``status.status_line``)."""
        thin = f" rethinned voxel={self.voxel:.2f}" if self.rethinned else ""
        detail = f"pts={self.n_points}{thin} cands={self.n_candidates}"
        return status.status_line(self.record(offset), detail)


class Localizer:
    """Floor-plan state (features, gate maps, the compiled front-end) built once, then any
    number of sequences localized against it.

    Args:
        floorplan: the ``Floorplan`` (frame B).
        params: ``LocalizeParams``.
    """

    def __init__(self, floorplan, params: LocalizeParams | None = None):
        self.floorplan = floorplan
        self.params = params or LocalizeParams()
        self._fe = FrontEnd([floorplan], self.params.frontend, chunk=1)
        self._maps = decision_maps(floorplan)
        self._search = rival_fields(floorplan)  # the rival search's view of the plan
        self._cut = None  # (seq, its Windows, its Odometer) of the last n_windows call

    def windows(self, seq) -> W.Windows:
        """The windows of ``seq`` (as the batch path cuts them)."""
        return W.cut(seq, self.params.window)

    def n_windows(self, seq) -> int:
        """The number of windows of ``seq``. The windows depend on the LiDAR odometry (its
        jump test splits segments), so they are cut here, once: ``run(seq)`` reuses them."""
        if self._cut is None or self._cut[0] is not seq:
            odometer = Odometer(self.params.window.scan_match)
            self._cut = (seq, W.cut(seq, self.params.window, odometer=odometer), odometer)
        return len(self._cut[1])

    def run(self, seq, variant: str = "ours") -> Iterator[WindowResult]:
        """Streams the windows of ``seq``; yields one ``WindowResult`` per window."""
        return self.follow([seq], variant)

    def follow(self, prefixes, variant: str = "ours") -> Iterator[WindowResult]:
        """Streams the windows of a recording that grows (the live path).

        Args:
            prefixes: ever longer ``ScanSequence``s of one recording, each extending the one
                before; every window complete in a prefix and not yet seen is decided.
                Windows are causal, so the results are ``run``'s on the last prefix.
            variant: a key of ``decision.OURS_VARIANTS``.
        """
        init, prev_end, cur, base = None, -1, None, 0
        cap = self.params.window.capacity
        for seq, w, k in self._new_windows(prefixes):
            kf = w.keyframes
            j0, j1 = w.bounds[k]
            seg = w.segments[: j1 + 1]
            if cur is not None and seg[j0] != cur:
                # An odometry jump (a restart): the frames before and after are incommensurable,
                # so the layer starts over (as the batch path does, decision.split_segments).
                init = None
            if init is None:
                base = int(np.flatnonzero(seg == seg[j0])[0])
                prev_end = base - 1
            cur = seg[j0]
            if init is None:
                init = SelectiveInitializer(
                    self._maps,
                    self.params.decision,
                    variant=variant,
                    k_cap=bucket(len(w), 8),
                    j_cap=self.params.frontend.J,
                    t_cap=bucket(len(kf), 256),
                    plan=self._search,
                )
            one = W.window(w, k)
            wb = W.pack([(seq, one, 0)], capacity=bucket(cap, 256))
            cand = self._fe.register(wb.submaps, wb.building, keep=True)
            m = cand.mask[0]
            traj = w.odometry[prev_end + 1 : j1 + 1]
            prev_end = int(j1)
            dec = init.update(
                cand.pose[0][m],
                cand.score[0][m],
                w.X[k],
                traj,
                t=float(w.t[k]),
                window_start=int(j0) - base,
                evidence=(w.points[k], w.origins[k]),
            )
            yield WindowResult(
                decision=dec,
                first=int(kf[j0]),
                last=int(kf[j1]),
                t=float(w.t[k]),
                X=np.asarray(w.X[k]),
                n_points=len(w.points[k]),
                voxel=float(w.voxel[k]),
                n_candidates=int(m.sum()),
                frontend_reason=int(cand.reason[0]),
                rethinned=bool(W.rethinned(w)[k]),
                X_input=np.asarray(w.X_input[k]),
            )

    def _new_windows(self, prefixes) -> Iterator[tuple]:
        """``(seq, windows, k)`` of every window of the prefixes not seen before (``k``
        indexes ``windows``, which holds only the new windows of ``seq``)."""
        seen = 0
        # One LiDAR odometer for the recording: each prefix only adds keyframes to it.
        odometer = Odometer(self.params.window.scan_match)
        for seq in prefixes:
            if self._cut is not None and self._cut[0] is seq and seen == 0:
                # Cut by n_windows (the CLI counts the windows first); used once.
                (_, w, odometer), self._cut = self._cut, None
            else:
                w = W.cut(seq, self.params.window, start=seen, odometer=odometer)
            for k in range(len(w)):
                yield seq, w, k
            seen += len(w)


def localize(floorplan, seq, params: LocalizeParams | None = None) -> list:
    """All ``WindowResult``s of one sequence (convenience wrapper of ``Localizer.run``)."""
    return list(Localizer(floorplan, params).run(seq))
