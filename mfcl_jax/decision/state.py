"""What the layer carries from one window to the next (``LayerState``), what it reads and
never changes (``World``: the plan, the thresholds, the lanes, the static capacities) and what
each window brings (``WindowEvidence``). Fixed shapes throughout; ``history`` holds the
buffers."""

from __future__ import annotations

from dataclasses import dataclass, field

import jax

from mfcl_jax.decision import baselines, machine, rivals
from mfcl_jax.decision.grid import Grid
from mfcl_jax.decision.history import Caps, History, Path
from mfcl_jax.decision.lanes import Lanes, LaneSpec
from mfcl_jax.decision.maps import DecisionMaps
from mfcl_jax.decision.params import DecisionParams
from mfcl_jax.frontend.path_search import PlanFields

__all__ = ["World", "WindowEvidence", "LayerState"]


@dataclass(frozen=True)
class World:
    """What every update reads and none changes: the plan, the thresholds, the lanes.

    ``fields``/``n_img``: the rival search's view of the plan and its static image side
    (None / 0 when the lanes search no rivals)."""

    maps: DecisionMaps
    params: DecisionParams
    lanes: Lanes
    fields: PlanFields | None
    caps: Caps = field(metadata=dict(static=True), default=Caps())
    spec: LaneSpec | None = field(metadata=dict(static=True), default=None)
    n_img: int = field(metadata=dict(static=True), default=0)
    rival_params: rivals.RivalParams = field(metadata=dict(static=True),
                                             default=rivals.DEFAULT_RIVALS)  # fmt: skip


jax.tree_util.register_dataclass(
    World, data_fields=["maps", "params", "lanes", "fields"],
    meta_fields=["caps", "spec", "n_img", "rival_params"],
)  # fmt: skip


@dataclass(frozen=True)
class WindowEvidence:
    """One window as the layer sees it (leaves may carry batch axes).

    Attributes:
        Y: ``(J, 3)`` candidate poses ``^B T_{S_k}``; score: ``(J,)``; mask: ``(J,)``.
        X: ``(3,)`` odometry pose ``^L T_{S_k}`` of the window's last scan.
        traj: ``(S, 3)`` keyframe poses since the previous window, the last one this
            window's last scan; traj_mask: ``(S,)`` (a prefix).
        head: ``(S0, 3)`` keyframes before ``traj`` on the first window of a segment (the
            history is empty there, so only the path takes them); head_mask: ``(S0,)``.
        start: ``()`` int32 index of the window's first keyframe since the segment began.
        ev_points, ev_origins: ``(P, 2)`` evidence sample (window frame); ev_mask: ``(P,)``.
        valid: ``()`` bool (false: padding, state unchanged).
        last: ``()`` bool the run's last window (forced-choice baselines commit there).
        restart: ``()`` bool the first window of a new odometry segment.
        end_points: ``(P, 2)`` the points of the window's last scan (window frame,
            ``windows.end_sample``), fitted to the plan where a lane reports a commit
            (``drift``); end_mask: ``(P,)``. ``None``: no such sample, the check is off.
    """

    Y: jax.Array
    score: jax.Array
    mask: jax.Array
    X: jax.Array
    traj: jax.Array
    traj_mask: jax.Array
    head: jax.Array
    head_mask: jax.Array
    start: jax.Array
    ev_points: jax.Array
    ev_origins: jax.Array
    ev_mask: jax.Array
    valid: jax.Array
    last: jax.Array
    restart: jax.Array
    end_points: jax.Array | None = None
    end_mask: jax.Array | None = None


@dataclass(frozen=True)
class LayerState:
    """Everything the layer remembers (fixed shapes; see ``history``)."""

    world: World
    history: History
    path: Path
    held: machine.Held  # (L,) per lane
    base: baselines.BaselineState
    rivals: jax.Array  # (E, 3) placements of the path found by the rival search
    rivals_ok: jax.Array  # (E,) bool
    searches: jax.Array  # () int32
    u_tests: jax.Array  # () int32 uniqueness tests in this odometry segment
    n_rejected: jax.Array  # () int32 non-finite candidates rejected so far
    grid: Grid | None = None  # the evidence grid (``grid``; None: no lane keeps one)


for _cls in (WindowEvidence, LayerState):
    jax.tree_util.register_dataclass(
        _cls, data_fields=list(_cls.__dataclass_fields__), meta_fields=[]
    )
