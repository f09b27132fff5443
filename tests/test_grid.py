"""The evidence grid (``decision.grid``): what it accumulates is the path's log-likelihood on
its pooled fields, read placement by placement (the FFT, the robot-centred shift and the
sub-cell offsets checked against a direct sum), its leader is the truth where one place fits,
and the lane that reads it commits early at the truth, never in one of congruent rooms, and
decides alike as a robot and as a batch."""

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.decision import grid as G
from mfcl_jax.frontend.path_fields import plan_fields, sample_field
from mfcl_jax.sim.synthetic import PITCH, row_of_rooms
from tests._walks import congruent_walk, early_state, unique_walk

NO_DRIFT = G.GridParams(drift_xy=0.0, drift_deg=0.0, n_img=64)


def _fields(fp):
    return jax.tree.map(jnp.asarray, plan_fields(fp.rasterize()))


def _direct(fields, pose, pts, ok, metres, gp):
    """The pooled log-likelihood of one window's evidence at the robot's plan ``pose``."""
    free, fok = G._samples(pts, pts * 0.0, ok, gp.ray_fracs)  # origins at the robot
    q = se2.apply(pose, pts)
    f = se2.apply(pose, free)
    hit = sample_field(fields.g_hit, fields.origin, fields.g_res, q, 0.0)
    fr = sample_field(fields.g_free, fields.origin, fields.g_res, f, 0.0)
    wp = metres / float(ok.sum())
    wf = metres / float(fok.sum())
    base = metres * (fields.g_off[0] + fields.g_off[1])
    return float(jnp.sum(jnp.where(ok, hit, 0.0)) * wp + jnp.sum(jnp.where(fok, fr, 0.0)) * wf
                 + base)  # fmt: skip


def _pose_at(g, fields, X, gp, t, iy, ix):
    x, y, th = G._poses(g, fields, X, gp)
    return jnp.stack([x[t, iy, ix], y[t, iy, ix], th[t]])


def test_the_grid_holds_the_pooled_log_likelihood_of_every_placement():
    fp = row_of_rooms(widths=(PITCH, 9.0, 5.5))
    fields = _fields(fp)
    rng = np.random.default_rng(0)
    # two windows' evidence (window frames, origins at the robot), the robot 2.3 m on
    pts = [jnp.asarray(rng.uniform(-6, 6, (64, 2)), jnp.float32) for _ in range(2)]
    ok = jnp.asarray(rng.random(64) < 0.9)
    X1 = jnp.asarray([0.5, -0.3, 0.4], jnp.float32)
    X2 = se2.compose(X1, jnp.asarray([2.3, 0.4, 0.25], jnp.float32))
    g = G.empty(fields.g_hit.shape, NO_DRIFT)
    add = jax.jit(G.add_window, static_argnames="gp")  # one program for both windows
    g1 = add(g, fields, X1, 6.0, pts[0], pts[0] * 0.0, ok, gp=NO_DRIFT)
    g2 = add(g1, fields, X2, 8.3, pts[1], pts[1] * 0.0, ok, gp=NO_DRIFT)
    hc, wc = fields.g_hit.shape
    for t, iy, ix in [(0, hc // 2, wc // 3), (13, 10, 40), (40, hc // 2, wc // 2), (71, 7, 70)]:
        p1 = _pose_at(g1, fields, X1, NO_DRIFT, t, iy, ix)
        want1 = _direct(fields, p1, pts[0], ok, 6.0, NO_DRIFT)
        np.testing.assert_allclose(float(g1.value[t, iy, ix]), want1, rtol=2e-4, atol=2e-3)
        # after the second window the cell is where the robot is now; its first window was
        # seen from the placement the odometry step leads back to
        p2 = _pose_at(g2, fields, X2, NO_DRIFT, t, iy, ix)
        back = se2.compose(p2, se2.between(X2, X1))
        want2 = _direct(fields, back, pts[0], ok, 6.0, NO_DRIFT) + _direct(
            fields, p2, pts[1], ok, 2.3, NO_DRIFT)  # fmt: skip
        np.testing.assert_allclose(float(g2.value[t, iy, ix]), want2, rtol=2e-4, atol=2e-3)


# --- the lane (``ours_grid``) inside ``layer.update`` -----------------------------------------

A = np.array([1.0, -2.0, 0.4])  # hidden ^B T_L
K, J = 8, 16
COMMIT = 2


def _world(fp):
    return early_state(fp, ("ours", "ours_grid"))


def _robot(fp, run):
    """Lanes ``ours`` and ``ours_grid`` window by window as a robot: leaves ``(K, 2, ...)``."""
    from tests._layer import evidence_of, stepwise

    state, _ = _world(fp)
    return stepwise(state, evidence_of(run))[1]


def test_a_unique_path_commits_on_the_grid_before_the_count_and_at_the_truth():
    from mfcl_jax.decision.lanes import GRID_MARGIN

    fp, run = unique_walk(A, K, J)
    d = _robot(fp, run)
    ours, grid = d.state[:, 0], d.state[:, 1]
    assert (grid == COMMIT).any(), (grid.tolist(), d.llr[:, 1].tolist())
    k_g = int(np.argmax(grid == COMMIT))
    k_o = int(np.argmax(ours == COMMIT)) if (ours == COMMIT).any() else K
    assert k_g < k_o, (k_g, k_o, d.llr[:, 1].tolist())
    # at the first window whose margin reaches the lane's, not before
    assert k_g == int(np.argmax(d.llr[:, 1] >= GRID_MARGIN)), d.llr[:, 1].tolist()
    assert np.isnan(d.llr[:, 0]).all()  # the count lane reads no grid
    dxy, dth = se2.distance_pair(d.anchor[k_g, 1], A)
    assert float(dxy) < 0.3 and np.rad2deg(float(dth)) < 2.0
    np.testing.assert_array_equal(d.test_anchor[k_g, 1], d.anchor[k_g, 1])


def test_a_walk_inside_one_of_four_congruent_rooms_never_commits_on_the_grid():
    from mfcl_jax.decision.lanes import GRID_MARGIN

    fp, run = congruent_walk(A, K, J)  # four congruent rooms, doors at the same place
    d = _robot(fp, run)
    assert not (d.state[:, 1] == COMMIT).any(), (d.state[:, 1].tolist(), d.llr[:, 1].tolist())
    ran = np.isfinite(d.llr[:, 1])
    assert ran.any() and (d.llr[ran, 1] < GRID_MARGIN).all()


def test_the_robot_and_the_batch_decide_the_grid_lane_alike():
    """One jitted ``update`` per window (the robot) and ``vmap`` over runs of
    ``lax.scan(update)`` (the batch, ``decision.runs.scan_runs``): the same states, anchors
    and margins, window by window."""
    from mfcl_jax.decision.runs import scan_runs
    from tests._layer import CAPS, evidence_of

    fp, run = unique_walk(A, K, J)
    robot = _robot(fp, run)
    _, (maps, fields, p, lanes, spec) = _world(fp)
    ev = jax.tree.map(lambda a: np.stack([a, a]), evidence_of(run))  # two runs, one building
    stack = lambda t: jax.tree.map(lambda a: jnp.asarray(a)[None], t)  # noqa: E731
    batch = jax.jit(scan_runs, static_argnames=("caps", "spec", "n_img"))(
        stack(maps), stack(fields), np.zeros(2, np.int32), p.as_arrays(),
        jax.tree.map(jnp.asarray, lanes), ev, caps=CAPS, spec=spec, n_img=0,
    )  # fmt: skip
    for r in range(2):
        b = jax.tree.map(lambda a, r=r: np.asarray(a)[r], batch)
        np.testing.assert_array_equal(b.state, robot.state)
        np.testing.assert_allclose(b.anchor, robot.anchor, atol=1e-4)
        np.testing.assert_allclose(b.llr, robot.llr, rtol=1e-4, atol=1e-3)
