"""Decision layer as a robot runs it: one jitted ``update`` per window decides as the batch,
a restart starts a new segment, and a run of 500 windows outlives the fixed capacities.
"""

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.decision import layer
from tests._decision_row import ROW, A, lattice_cands, ours, probe_cands, run_all, run_of
from tests._layer import CAPS, K, T, evidence_of, lanes_of, step, stepwise, window


def test_a_robot_calling_update_decides_as_the_batch():
    """The robot's path (one jitted ``update`` per window, unbatched) and the batch's (``vmap``
    over runs of ``lax.scan(update)``) are one function: the same decisions."""
    run = run_of(lattice_cands)
    out = ours(run_all([run]))
    p, lanes, spec = lanes_of(ours=("ours",), baselines=False)
    maps = jax.tree.map(lambda a: a[0], ROW)
    state = layer.init(maps, p.as_arrays(), CAPS, jax.tree.map(jnp.asarray, lanes), spec)
    ev = evidence_of(run)
    for k in range(K):
        state, d = step()(state, window(ev, k))
        d = jax.tree.map(lambda a: np.asarray(a[0]), d)
        assert int(d.state) == out.state[k] and int(d.kind) == out.kind[k], k
        assert int(d.b1) == out.b1[k] and int(d.b2) == out.b2[k]
        np.testing.assert_allclose(d.anchor, out.anchor[k], atol=1e-4)


def test_a_restart_decides_the_new_segment_as_a_run_of_its_own():
    """An odometry jump: the layer starts over at the window flagged ``restart``; the
    windows after it are decided as the same windows would be in a run of their own."""
    run = run_of(probe_cands)
    one = evidence_of(run)
    two = jax.tree.map(lambda a: np.concatenate([a, a]), one)  # the walk again, after a jump
    assert two.restart.tolist() == [True] + [False] * (K - 1) + [True] + [False] * (K - 1)
    two = type(two)(**{**two.__dict__, "last": np.arange(2 * K) == 2 * K - 1})
    p, lanes, spec = lanes_of(ours=("ours",), baselines=False)
    state = layer.init(jax.tree.map(lambda a: a[0], ROW), p.as_arrays(),
                       CAPS, jax.tree.map(jnp.asarray, lanes), spec)  # fmt: skip
    _, d = stepwise(state, two)
    first, again = (jax.tree.map(lambda a, s=s: np.asarray(a)[s, 0], d)
                    for s in (slice(0, K), slice(K, 2 * K)))  # fmt: skip
    for f in ("state", "kind", "b1", "b2", "reason"):
        np.testing.assert_array_equal(getattr(first, f), getattr(again, f), err_msg=f)
    np.testing.assert_allclose(first.anchor, again.anchor, atol=1e-5)
    assert 2 in first.state.tolist()


def test_a_run_of_500_windows_outlives_the_capacities_and_says_so():
    """A long run: the history keeps the newest ``CAPS.windows`` windows and the newest
    ``CAPS.traj`` keyframes (fixed shapes, so every window costs the same); older windows leave
    the consensus and are counted (``Decision.dropped``), a commit keeps being tracked, the
    path keeps its distance, and no number turns non-finite."""
    run = run_of(probe_cands)
    one = evidence_of(run)
    n = 500
    reps = -(-n // K)
    # the same walk again and again, without a restart: the path goes on (a loop)
    many = jax.tree.map(lambda a: np.concatenate([a] * reps)[:n], one)
    ends = np.asarray(run["window_end"])
    starts = np.concatenate([np.asarray(run["window_start"]) + r * (ends[-1] + 1)
                             for r in range(reps)])[:n]  # fmt: skip
    many = type(many)(**{**many.__dict__, "restart": np.arange(n) == 0,
                         "start": starts.astype(np.int32),
                         "head": np.zeros_like(one.head[:1].repeat(n, 0)),
                         "head_mask": np.zeros_like(one.head_mask[:1].repeat(n, 0)),
                         "last": np.arange(n) == n - 1})  # fmt: skip
    first = jax.tree.map(lambda a: a[:1], one)  # window 1 brings its whole keyframe prefix
    p, lanes, spec = lanes_of(ours=("ours",), baselines=False)
    state = layer.init(jax.tree.map(lambda a: a[0], ROW), p.as_arrays(),
                       CAPS, jax.tree.map(jnp.asarray, lanes), spec)  # fmt: skip
    state, d0 = step()(state, window(first, 0))
    rest = jax.tree.map(lambda a: a[1:], many)
    rest = type(rest)(**{**rest.__dict__, "restart": np.zeros(n - 1, bool)})
    state, d = stepwise(state, rest)
    d = jax.tree.map(lambda a: np.asarray(a)[:, 0], d)
    assert d.dropped[-1] == n - K  # every window beyond the capacity is counted
    assert (np.diff(d.dropped) >= 0).all() and d.dropped[K - 2] == 0
    assert int(state.history.n) == K and int(state.path.n) == T
    assert int(state.path.total) > T  # keyframes kept counting past the buffer
    assert 2 in d.state.tolist() and d.state[-1] == 2  # the commit is held to the end
    assert np.isfinite(d.anchor).all() and np.isfinite(float(state.path.dist))
    dxy, _ = se2.distance_pair(d.anchor[-1], A)
    assert float(dxy) < 0.1
