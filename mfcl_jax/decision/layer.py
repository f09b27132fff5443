"""The decision layer as a pure state machine, the way optax writes an optimizer.

``init(maps, params, caps, lanes) -> LayerState`` and ``update(LayerState, WindowEvidence)
-> (LayerState, Decision)`` on fixed-size device buffers (``history``). A robot calls the
jitted ``update`` once per window; the study and the benchmark run ``vmap`` over runs of
``lax.scan(update)`` (``decision.runs``). Both are the same function, so they decide alike.

One update: anchor the window's candidates (``H = Y X^-1``, non-finite ones rejected and
counted), extend the path and every kept candidate's gate walk by the new keyframes, push the
window, then per core mode (gate on/off, symmetry set) the shared core (``rule.core``), the
certification where some lane needs it (``rule.needs_certificate``, through ``sparse_cond``:
a batch pays only for the windows that need one), each lane's rule (``rule.finish``) and
commit machine (``machine.step``), the check of every reported commit against the window's
last scan (``drift``; off where ``init`` has no plan fields or the window no end
sample), the storey check (``storey``: no commit on a place several storeys share), and the
baselines (``baselines.step``). Where the primary lane is about to enter COMMIT (and its run
has searches left) the path is searched for rivals (``rivals.search``) and the window is
decided again with them.

A window with ``restart`` begins a new odometry segment: the layer starts over (poses across
a jump are in incommensurable frames); one with ``valid`` false (a batch's padding) is a no-op.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import baselines, drift, early, gate, machine, passes, rivals, rule
from mfcl_jax.decision import grid as G
from mfcl_jax.decision.anchors import sanitize
from mfcl_jax.decision.history import (
    Caps,
    History,
    Path,
    empty_history,
    empty_path,
    push_path,
    push_window,
)
from mfcl_jax.decision.lanes import Lanes, LaneSpec
from mfcl_jax.decision.maps import DecisionMaps
from mfcl_jax.decision.outcome import COMMIT, Decision
from mfcl_jax.decision.params import DecisionParams
from mfcl_jax.decision.passes import where_tree as _where
from mfcl_jax.decision.state import LayerState, WindowEvidence, World
from mfcl_jax.decision.storey import leave_shared
from mfcl_jax.frontend.path_search import PlanFields

__all__ = ["World", "WindowEvidence", "LayerState", "init", "update", "advance", "split", "join"]


def split(state: LayerState) -> tuple[World, dict]:
    """``(world, memory)``: what never changes, and the rest (a robot donates the memory's
    buffers to the next update and keeps the world)."""
    mem = {k: v for k, v in state.__dict__.items() if k != "world"}
    return state.world, mem


def join(world: World, memory: dict) -> LayerState:
    return LayerState(world=world, **memory)


def _fresh(world: World) -> LayerState:
    n_lanes = world.lanes.use_gate.shape[0]
    e = world.rival_params.n_rivals * world.rival_params.max_searches
    held = jax.tree.map(lambda a: jnp.broadcast_to(a, (n_lanes, *a.shape)), machine.initial())
    return LayerState(
        world, empty_history(world.caps), empty_path(world.caps), held,
        baselines.start(world.lanes.confidence_ratio.shape[0]), jnp.zeros((e, 3), jnp.float32),
        jnp.zeros(e, bool), jnp.int32(0), jnp.int32(0), jnp.int32(0),
        G.empty(world.fields.g_hit.shape) if world.spec.grid else None,
    )  # fmt: skip


def init(maps: DecisionMaps, params: DecisionParams, caps: Caps, lanes: Lanes,
         spec: LaneSpec, fields: PlanFields | None = None, n_img: int = 0,
         rival_params: rivals.RivalParams = rivals.DEFAULT_RIVALS) -> LayerState:  # fmt: skip
    """The state before the first window (``lanes.lanes`` gives ``lanes``, ``spec``)."""
    if spec.searches and fields is None:
        raise ValueError("init: a lane reads the plan's search fields; pass fields=")
    if (spec.primary >= 0 or spec.unique) and n_img <= 0:
        raise ValueError("init: a lane searches the plan for the path; pass n_img=")
    world = World(maps, params, lanes, fields, caps, spec, n_img, rival_params)
    return _fresh(world)


def advance(state: LayerState, traj, traj_mask) -> LayerState:
    """Keyframes that arrive without a window (more than ``Caps.step`` since the last one)."""
    h = state.history
    walk = gate.extend_walk(state.world.maps, h.H, traj, traj_mask, h.walk)
    return LayerState(**{**state.__dict__, "history": History(**{**h.__dict__, "walk": walk}),
                         "path": push_path(state.path, traj, traj_mask)})  # fmt: skip


def _cores(world: World, h: History, path: Path, cons):
    """``rule.Core`` per core mode ``(M, ...)``."""
    k = h.n - 1
    valid = jnp.arange(path.pose.shape[0]) < path.n
    ug = jnp.asarray([m[0] for m in world.spec.modes])
    q = jnp.asarray([m[1] for m in world.spec.modes], jnp.int32)

    def one(use_gate, qi):
        sym = jax.tree.map(lambda a: a[qi], world.maps.sym)
        return rule.core(k, h.H, h.score, h.mask, cons, h.s_end, h.start, h.end, path.pose,
                         valid, world.maps, sym, world.params, use_gate,
                         world.caps.probe_shifts)  # fmt: skip

    return jax.vmap(one)(ug, q)


def update(state: LayerState, ev: WindowEvidence, batched: bool = False
           ) -> tuple[LayerState, Decision]:  # fmt: skip
    """One window: the new state and every lane's ``Decision`` (leaves ``(L, ...)``).
    ``batched`` (static): the program form for ``vmap`` over runs
    (``passes.decided_batched``; ``passes.decided`` otherwise);
    both forms decide alike."""
    world = state.world
    p = world.params
    before = state
    fresh = _fresh(world)
    fresh = LayerState(**{**fresh.__dict__, "n_rejected": state.n_rejected})
    state = _where(ev.restart, fresh, state)
    H = se2.anchor(ev.Y.astype(jnp.float32), ev.X[None].astype(jnp.float32))
    H, score, mask, bad = sanitize(H, ev.score, ev.mask)
    path = push_path(push_path(state.path, ev.head, ev.head_mask), ev.traj, ev.traj_mask)
    h = state.history
    walk = gate.extend_walk(world.maps, h.H, ev.traj, ev.traj_mask, h.walk)
    pvalid = jnp.arange(path.pose.shape[0]) < path.n
    new_walk = gate.extend_walk(world.maps, H, path.pose, pvalid, gate.start_walk(H.shape[:1]))
    end = path.total - 1
    h = push_window(History(**{**h.__dict__, "walk": walk}), dict(
        H=H, score=score, mask=mask, walk=new_walk, support=jnp.zeros(mask.shape, jnp.int32),
        start=ev.start, end=end, s_end=path.dist, X=ev.X, ev_points=ev.ev_points,
        ev_origins=ev.ev_origins, ev_mask=ev.ev_mask,
    ))  # fmt: skip
    k = h.n - 1
    cons = h.walk.consistency()
    cores = _cores(world, h, path, cons)
    u_tests, uniq, gstat, grid = state.u_tests, None, None, state.grid
    c0 = jax.tree.map(lambda a: a[0], cores)  # mode 0: the gate on, default symmetries
    if world.spec.unique:
        open_lane = jnp.any(world.lanes.use_unique & ~state.held.committed)
        uniq, u_tests = early.unique_test(world, h, path, c0, u_tests, open_lane, ev.valid)
    if world.spec.grid:
        open_lane = jnp.any(world.lanes.use_grid & ~state.held.committed)
        grid, gstat = early.grid_test(world, grid, h, path, c0, ev, open_lane)

    ops = (world, h, cores, state.held, state.rivals, state.rivals_ok, uniq, gstat)
    riv, riv_ok, searches, searched, held, out = (passes.decided_batched if batched
        else passes.decided)(ops, state.searches, ev.valid)  # fmt: skip
    if world.fields is not None and ev.end_points is not None:
        # every reported commit against the window's last scan
        poses = se2.compose(out.anchor, ev.X[None].astype(out.anchor.dtype))
        v = drift.check(world.fields, poses, out.state == COMMIT, ev.end_points, ev.end_mask)
        held, out = machine.leave_drifted(held, out, v)
    # a commit on a place of several congruent storeys names no storey
    held, out = leave_shared(world.maps, held, out, ev.traj, ev.traj_mask, ev.X)
    n_rejected = state.n_rejected + bad
    out = Decision(**{**out.__dict__, "searched": jnp.broadcast_to(searched, out.state.shape),
                      "n_rejected": jnp.broadcast_to(n_rejected, out.state.shape),
                      "dropped": jnp.broadcast_to(h.dropped, out.state.shape)})  # fmt: skip
    base = state.base
    support = h.support
    if world.spec.baselines:
        base, support, bdec = baselines.step(
            state.base, h.H, h.score, h.mask, cons, h.support, k, ev.last, p,
            world.lanes.confidence_ratio, world.lanes.support_ratio,
        )  # fmt: skip
        bdec = jax.tree.map(lambda a: a.reshape(-1, *a.shape[2:]), bdec)
        bdec = Decision(**{**bdec.__dict__, "n_rejected": jnp.broadcast_to(
            n_rejected, bdec.state.shape)})  # fmt: skip
        out = jax.tree.map(lambda a, b: jnp.concatenate([a, b], axis=0), out, bdec)
    h = History(**{**h.__dict__, "support": support})
    new = LayerState(world, h, path, held, base, riv, riv_ok, searches, u_tests=u_tests,
                     n_rejected=n_rejected, grid=grid)  # fmt: skip
    return _where(ev.valid, new, before), out
