"""The uniqueness lane (``decision.uniqueness`` inside ``layer.update``): it commits to the one
placement that explains the path as soon as the test holds, earlier than the count of windows
where the building allows it, and never where a congruent copy explains the path as well."""

import numpy as np

from mfcl_jax import se2
from mfcl_jax.decision.rivals import image_size
from mfcl_jax.sim.synthetic import PITCH, row_of_rooms
from tests._layer import evidence_of, stepwise
from tests._walks import congruent_walk, early_state, unique_walk

A = np.array([1.0, -2.0, 0.4])  # hidden ^B T_L
K, J = 8, 16
COMMIT = 2


def _decide(fp, run):
    """Lanes ``ours`` and ``ours_unique_a2`` (alpha 1e-2) window by window: host leaves
    ``(K, 2, ...)``."""
    # one static shape for both scenes (the longer row's), so both tests share one program
    n_img = image_size([row_of_rooms(widths=(PITCH,) * 4)])
    state, _ = early_state(fp, ("ours", "ours_unique_a2"), n_img)
    return stepwise(state, evidence_of(run))[1]


def test_a_unique_path_commits_no_later_than_the_count_and_at_the_truth():
    # rooms of three different lengths: a walk through all of them fits one place only
    fp, run = unique_walk(A, K, J)
    d = _decide(fp, run)
    ours, uniq = d.state[:, 0], d.state[:, 1]
    assert (uniq == COMMIT).any(), (uniq.tolist(), d.llr[:, 1].tolist())
    k_u = int(np.argmax(uniq == COMMIT))
    k_o = int(np.argmax(ours == COMMIT)) if (ours == COMMIT).any() else K
    assert k_u < k_o, (k_u, k_o)  # the test, not the count, commits it
    # at the first window whose ratio reaches log(1 / alpha), not before
    assert k_u == int(np.argmax(d.llr[:, 1] >= np.log(1e2))), d.llr[:, 1].tolist()
    assert np.isnan(d.llr[:, 0]).all()  # the count lane reports no ratio
    dxy, dth = se2.distance_pair(d.anchor[k_u, 1], A)
    assert float(dxy) < 0.3 and np.rad2deg(float(dth)) < 2.0
    # the test's own placement A* is reported where it ran (what its ratio is judged by), and
    # the commit it makes is to A*; zero where it did not run
    tested = ~np.isnan(d.llr[:, 1])
    np.testing.assert_array_equal(d.test_anchor[k_u, 1], d.anchor[k_u, 1])
    assert (np.abs(d.test_anchor[tested, 1]).sum(-1) > 0).all()
    assert not d.test_anchor[~tested, 1].any() and not d.test_anchor[:, 0].any()


def test_a_walk_inside_one_of_four_congruent_rooms_never_commits():
    fp, run = congruent_walk(A, K, J)  # four congruent rooms, doors at the same place
    d = _decide(fp, run)
    assert not (d.state[:, 1] == COMMIT).any(), (d.state[:, 1].tolist(), d.llr[:, 1].tolist())
    ran = np.isfinite(d.llr[:, 1])
    assert (d.llr[ran, 1] < np.log(1e2)).all()


def test_a_uniqueness_lane_alone_gets_the_plan_fields_its_search_needs():
    """Lanes of the uniqueness test without the rival-searching ``ours`` lane (the benchmark's
    ``policies=ours_unique_a2``): the buildings still carry the search's plan fields (it
    raised in ``layer.init`` before). Every lane set gets the fields (the drift check of a
    commit reads them); only a searching one gets an image size."""
    from mfcl_jax.decision import make_lanes
    from mfcl_jax.decision.runs import stack_buildings

    fp = row_of_rooms(widths=(PITCH, 9.0, 5.5))
    for ours, primary in ((("ours_unique_a2",), None), (("paper",), "paper")):
        spec = make_lanes(None, ours, False, primary)[2]
        b = stack_buildings([fp], spec)
        assert spec.searches == (ours[0] == "ours_unique_a2")
        assert b.fields is not None and (b.n_img > 0) == spec.searches
