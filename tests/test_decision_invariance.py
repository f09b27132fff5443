"""Decision layer invariances: C2 immunity to flooding below the top-1 (which flips the
support baseline), permutation invariance and rigid-motion equivariance.

All evaluations share one padded shape bucket so the jitted layer compiles once per lane set.
"""

import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mfcl_jax import se2
from mfcl_jax.sim.synthetic import row_of_rooms
from tests._decision_row import (
    NAMES,
    A,
    assert_same,
    base,
    base_out,
    lattice_cands,
    run_all,
    run_of,
)
from tests._layer import J, K, maps_of


@settings(max_examples=6)
@given(st.integers(1, 12), st.integers(0, 2**31 - 1))
def test_c2_immunity_flooding_below_top1(n, seed):
    rng = np.random.default_rng(seed)
    run = {k: np.array(v, copy=True) for k, v in base().items()}
    j0 = int(run["mask"][0].sum())
    for k in range(K):
        top = run["score"][k][run["mask"][k]].max()
        m = min(n, J - j0)
        near_alias = run["H"][k, 1] + rng.normal(0, 0.3, (m, 3)) * [1, 1, 0.05]
        anywhere = np.concatenate([rng.uniform(-10, 30, (m, 2)), rng.uniform(-3, 3, (m, 1))], -1)
        pick = rng.random(m) < 0.5
        run["H"][k, j0 : j0 + m] = np.where(pick[:, None], near_alias, anywhere)
        run["score"][k, j0 : j0 + m] = top * rng.uniform(0.0, 0.999, m)
        run["mask"][k, j0 : j0 + m] = True
    out = run_all([run])
    assert_same(base_out(), out)


def test_support_flips_under_flooding_while_ours_does_not():
    run = {k: np.array(v, copy=True) for k, v in base().items()}
    for k in range(K):
        run["H"][k, 3:13] = run["H"][k, 1] + np.linspace(-0.2, 0.2, 10)[:, None] * [1, 1, 0]
        run["score"][k, 3:13] = 0.5
        run["mask"][k, 3:13] = True
    out = run_all([run])
    assert_same(base_out(), out)
    sup = NAMES.index("support")
    a0, a1 = base_out().anchor[0, -1, sup], out.anchor[0, -1, sup]
    assert float(se2.distance_pair(a0, A)[0]) < 0.5
    assert float(se2.distance_pair(a1, A)[0]) > 5.0


@settings(max_examples=4)
@given(st.integers(0, 2**31 - 1))
def test_permutation_invariance(seed):
    rng = np.random.default_rng(seed)
    run = run_of(lattice_cands)
    perm = rng.permutation(J)
    run2 = dict(run, H=run["H"][:, perm], score=run["score"][:, perm], mask=run["mask"][:, perm])
    assert_same(run_all([run]), run_all([run2]), v=slice(None))


def test_rigid_motion_equivariance():
    """Moving the plan and the anchors by ``g`` moves every decision by ``g``. Exactly for the
    variants that read the plan through the gate only; the certifying ones re-score the
    evidence on the moved plan's rasters, whose discretisation perturbs the scores by a few
    hundredths, so the first commit may move by a window or two where an advantage sits at
    the margin."""
    g = np.array([4.0, -6.0, 0.6])
    maps_g = maps_of(row_of_rooms().transformed(g))
    run = run_of(lattice_cands)
    run_g = dict(run, H=np.asarray(se2.compose(g, run["H"]), np.float32))
    a, b = run_all([run]), run_all([run_g], maps=maps_g)
    exact = [NAMES.index(n) for n in ("paper", "no_probe", "consensus_only")]
    for f in ("state", "kind", "b1", "b2"):
        np.testing.assert_array_equal(getattr(a, f)[..., exact], getattr(b, f)[..., exact], f)
    first = lambda s: int(np.argmax(np.append(np.asarray(s) == 2, True)))  # noqa: E731
    for n in ("ours", "ours_b2_d1", "ours_b4_d2"):
        i = NAMES.index(n)
        assert abs(first(a.state[0, :, i]) - first(b.state[0, :, i])) <= 2, n
    np.testing.assert_array_equal(a.b1, b.b1)
    moved = np.asarray(se2.compose(g, a.anchor[..., exact, :]))
    dxy, dth = se2.distance_pair(moved, b.anchor[..., exact, :])
    assert float(jnp.max(dxy)) < 1e-3 and float(jnp.max(dth)) < 1e-4
    tr = (a.kind[..., exact] == 1) & (b.kind[..., exact] == 1)
    rot = np.asarray(se2.rotate(g[2], a.tau[..., exact, :][tr]))
    np.testing.assert_allclose(rot, b.tau[..., exact, :][tr], atol=1e-3)
