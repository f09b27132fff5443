"""The decision layer on synthetic runs (``sim.synthetic.make_run`` dicts):
``vmap`` over runs of ``lax.scan(layer.update)``, compiled once per lane set for one padded
map shape, as ``decision.runs`` does for real batches.

Every test building is padded to one grid and one room capacity, and every batch to a
multiple of ``RUNS`` runs (padding runs are ``valid``-false and leave no trace), so the
tests of a lane set share one compiled program (in process, and across the suite's workers
through the compilation cache): a compilation of the layer costs several seconds."""

from functools import cache

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.decision import Caps, decision_maps, layer, make_lanes
from mfcl_jax.decision.lanes import COUNT_VARIANTS
from mfcl_jax.decision.layer import WindowEvidence
from mfcl_jax.decision.maps import pad_maps
from mfcl_jax.decision.runs import scan_runs
from mfcl_jax.sim.synthetic import GRID, N_ROOMS

K, J, T, STEP = 8, 16, 192, 48
RUNS = 4  # runs per compiled call (GRID, N_ROOMS: every test building's, sim.synthetic)
CAPS = Caps(windows=K, cands=J, traj=T, step=STEP, evidence=128)


def maps_of(fp, n_rooms=N_ROOMS):
    """``DecisionMaps`` of ``fp`` padded to the tests' grid, stacked as one building."""
    m = pad_maps(decision_maps(fp), GRID, n_rooms, n_motions=8, n_offsets=32)
    return jax.tree.map(lambda a: jnp.asarray(a)[None], m)


def evidence_of(run) -> WindowEvidence:
    """One run's windows as the layer sees them (``(K, ...)`` host arrays)."""
    X = np.asarray(run["X"], np.float32)
    H = np.asarray(run["H"], np.float32)
    Y = np.asarray(se2.compose(H, X[:, None, :]), np.float32)
    traj = np.asarray(run["traj"], np.float32)
    ends = np.asarray(run["window_end"])
    starts = np.asarray(run["window_start"])
    k = len(ends)
    tr = np.zeros((k, STEP, 3), np.float32)
    tm = np.zeros((k, STEP), bool)
    hd = np.zeros((k, T, 3), np.float32)
    hm = np.zeros((k, T), bool)
    prev = -1
    for i, e in enumerate(ends):
        chunk = traj[prev + 1 : e + 1]
        n = min(len(chunk), STEP)
        tr[i, :n], tm[i, :n] = chunk[len(chunk) - n :], True
        if len(chunk) > n:
            assert i == 0, "only the first window may bring more keyframes than STEP"
            hd[i, : len(chunk) - n], hm[i, : len(chunk) - n] = chunk[: len(chunk) - n], True
        prev = int(e)
    wm = np.asarray(run["window_mask"], bool)
    last = np.zeros(k, bool)
    last[np.flatnonzero(wm)[-1]] = True
    return WindowEvidence(
        Y=Y, score=np.asarray(run["score"], np.float32), mask=np.asarray(run["mask"], bool),
        X=X, traj=tr, traj_mask=tm, head=hd, head_mask=hm, start=starts.astype(np.int32),
        ev_points=np.asarray(run["ev_points"], np.float32),
        ev_origins=np.asarray(run["ev_origins"], np.float32),
        ev_mask=np.asarray(run["ev_mask"], bool), valid=wm, last=last,
        restart=np.arange(k) == 0,
    )  # fmt: skip


@cache
def _compiled():
    return jax.jit(scan_runs, static_argnames=("caps", "spec", "n_img", "rp"))


def lanes_of(params=None, ours=COUNT_VARIANTS, baselines=True):
    return make_lanes(params, ours, baselines, primary=None)


def evaluate_runs(runs, maps, params=None, ours=COUNT_VARIANTS, baselines=True):
    """Every lane's ``Decision`` at every window: host leaves ``(R, K, L, ...)``, and the
    lane names."""
    p, lanes, spec = lanes_of(params, ours, baselines)
    evs = [evidence_of(r) for r in runs]
    n = len(evs)
    blank = jax.tree.map(np.zeros_like, evs[0])  # valid false: a padding run
    evs += [blank] * (-n % RUNS)
    ev = jax.tree.map(lambda *x: np.stack(x), *evs)
    b = np.zeros(len(evs), np.int32)
    out = _compiled()(maps, None, b, p.as_arrays(), jax.tree.map(jnp.asarray, lanes), ev,
                      caps=CAPS, spec=spec)  # fmt: skip
    return jax.tree.map(lambda a: np.asarray(a)[:n], out), spec.names


@cache
def step():
    """The robot's jitted ``update``: one ``jax.jit`` for every test of a worker, one program
    per state shape."""
    return jax.jit(layer.update)


def window(ev, k):
    """Window ``k`` of ``evidence_of``'s arrays, on the device."""
    return jax.tree.map(lambda a: jnp.asarray(a[k]), ev)


def stepwise(state, ev):
    """``lax.scan(update)`` as a robot runs it, the jitted step once per window:
    ``(state, Decision)`` with host leaves ``(K, L, ...)``."""
    out = []
    for k in range(len(ev.valid)):
        state, d = step()(state, window(ev, k))
        out.append(jax.tree.map(np.asarray, d))
    return state, jax.tree.map(lambda *x: np.stack(x), *out)
