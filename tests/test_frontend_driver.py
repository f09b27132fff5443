"""FrontEnd driver: one compilation for the buildings given at construction, input order kept,
results equal to the kernel on each building's own features, later buildings bucketed apart."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _frontend_synth import batch, make_submap

from mfcl_jax import se2
from mfcl_jax.frontend import build_features, make_register, registration
from mfcl_jax.frontend.driver import FrontEnd
from mfcl_jax.sim.scenes import get_scene

P = 1024
SCENES = ("three_rooms", "symmetric_bays")


def hit(pose, Y, xy=0.1, deg=1.0) -> bool:
    dxy, dth = se2.distance_pair(np.asarray(pose, np.float32), np.asarray(Y, np.float32))
    return bool((dxy < xy) & (dth < math.radians(deg)))


@pytest.fixture(scope="module")
def run():
    fps = [get_scene(s).floorplan for s in SCENES]
    subs = [
        make_submap(fps[1], (8.8, 3.0), (12.8, 4.4), 0.3, n_beams=180),
        make_submap(fps[0], (3.0, 3.0), (6.0, 5.0), -0.7, n_beams=180),
        make_submap(fps[0], (20.0, 4.0), (22.0, 8.0), 1.9, n_beams=180),
    ]
    building = np.array([1, 0, 0])
    fe = FrontEnd(fps, chunk=2)
    before = registration.TRACE_COUNT[0]
    c = fe.register(batch(subs, P), building)
    return fps, subs, building, fe, c, registration.TRACE_COUNT[0] - before


def test_one_compilation_for_the_buildings_given_at_construction(run):
    fps, _, _, fe, _, traced = run
    assert traced == 1
    shapes = {tuple(fe.features(b).sdf4.shape) for b in range(len(fps))}
    assert len(shapes) == 1
    assert fe.compile_s > 0 and fe.run_s > 0


def test_candidates_in_input_order_and_equal_to_the_kernel(run):
    fps, subs, building, _, c, _ = run
    assert c.pose.shape == (3, 32, 3) and c.mask[:, 0].all()
    # Rows come back in input order: each submap's top candidate is its truth (three_rooms has
    # no symmetry at these poses; the bays' tie is checked among the best-scoring ones).
    for i in (1, 2):
        assert hit(c.pose[i, 0], subs[i][2]), (i, c.pose[i, 0], subs[i][2])
    best = c.score[0] >= c.score[0, 0] - 1e-6
    assert any(hit(c.pose[0, j], subs[0][2]) for j in np.flatnonzero(best & c.mask[0]))
    # The shared bucket pads the plan; the kernel on the building's own features agrees.
    reg = make_register()
    own = reg(batch([subs[1], subs[2]], P), build_features(fps[0]))
    np.testing.assert_allclose(np.asarray(own.score[:, :5]), c.score[1:, :5], atol=1e-5)


def test_a_building_added_later_gets_its_own_bucket(run):
    fps, _, _, fe, _, _ = run
    shared = fe.features(0).sdf4.shape
    b = fe.add(get_scene("symmetric_bays").floorplan)
    assert fe.features(b).sdf4.shape != shared


def test_a_prepared_call_is_the_one_register_uses(run):
    """``FrontEnd.prepare`` compiles the call for a point capacity in the background (the
    study does it while it simulates); a ``register`` of that shape waits for it instead of
    tracing and compiling its own, and gives the same candidates."""
    from mfcl_jax.background import Pending

    fps, subs, building, _, c, _ = run
    fe = FrontEnd(fps, chunk=2)
    before = registration.TRACE_COUNT[0]
    fe.prepare(P)
    assert isinstance(next(iter(fe._compiled.values())), Pending)
    got = fe.register(batch(subs, P), building)
    assert registration.TRACE_COUNT[0] - before == 1  # the prepared trace only
    assert len(fe._compiled) == 1
    np.testing.assert_array_equal(got.pose, c.pose)
    np.testing.assert_array_equal(got.score, c.score)
