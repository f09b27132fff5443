"""The decision layer's reference scene for the tests: a row of congruent rooms walked end to
end, the candidate patterns of a lattice and of a probe, and the reference run decided once
per worker (``base_out``), shared by every file of the decision group that needs it."""

import functools

import jax
import numpy as np

from mfcl_jax.sim.synthetic import PITCH, make_run, row_of_rooms, shift, walk
from tests._layer import J, K, evaluate_runs, lanes_of, maps_of

A = np.array([1.0, -2.0, 0.4])  # hidden ^B T_L
# r1 -> r2 -> r1 -> r0 -> r3: the shifted aliases die only once both row ends are visited.
PATH = [[10, 2.5], [18, 2.5], [10, 2.5], [3, 2.5], [26, 2.5]]
ROW = maps_of(row_of_rooms())


def run_all(runs, maps=ROW, params=None):
    out, names = evaluate_runs(runs, maps, params)
    return out


NAMES = lanes_of()[2].names
OURS = NAMES.index("ours")


def lattice_cands(k, Y):
    # true and +p alias alternate as champion; a low-scored stray candidate.
    return [(Y, 1.0), (shift(Y, PITCH), 1.05 if k % 2 else 0.9), (shift(Y, 2.0, 1.0), 0.3)]


def probe_cands(k, Y):
    # the true anchor always wins; the +p image is never a champion (tie-broken away).
    return [(Y, 1.0 + 0.01 * k), (shift(Y, PITCH), 0.9), (shift(Y, -3.0, 0.5), 0.2)]


ROW_FP = row_of_rooms()


def run_of(cand_fn, path=PATH, anchor=A, fp=ROW_FP):
    return make_run(walk(path), anchor, K, cand_fn, J=J, fp=fp)


def ours(out, k=None):
    d = jax.tree.map(lambda x: x[0, :, OURS], out)
    return d if k is None else jax.tree.map(lambda x: x[k], d)


FIELDS = ("state", "kind", "b1", "b2", "margin", "n_groups", "n_champions")


def assert_same(a, b, v=slice(0, 5)):
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(a, f)[..., v], getattr(b, f)[..., v], err_msg=f)
    np.testing.assert_allclose(a.anchor[..., v, :], b.anchor[..., v, :], atol=1e-4)
    np.testing.assert_allclose(a.tau[..., v, :], b.tau[..., v, :], atol=1e-4)


@functools.cache
def base():
    """The reference run (built at first use, not at import: collection stays light)."""
    return run_of(probe_cands)


@functools.cache
def base_out():
    """``base()`` decided (at first use: collection stays free of compilation)."""
    return run_all([base()])
