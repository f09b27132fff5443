"""The labeller (``score.identifiability``): a run's label is a function of that run alone."""

import dataclasses

import numpy as np

from mfcl_jax import windows as W
from mfcl_jax.frontend import path_search as ps
from mfcl_jax.score.identifiability import label_runs
from mfcl_jax.sim.families import make_scene
from mfcl_jax.sources.simulated import simulate


def test_a_runs_label_does_not_depend_on_the_runs_labelled_before_it():
    # the benchmark labels only the runs missing from its cache, so the same run is labelled
    # alone or after others depending on what ran before: its label must be the same
    scene = make_scene("corridor", 1)
    recs = simulate(scene, list(scene.trajectories)[:2], [0])
    wins = [W.cut(r.seq, W.WindowParams(d_s=6.0)) for r in recs]
    r = scene.floorplan.rasterize()
    fields = ps.plan_fields(r, shape=tuple(-(-n // 128) * 128 for n in r.shape))
    alone = label_runs(recs[1:], wins[1:], lambda _: fields)[0]
    after = label_runs(recs, wins, lambda _: fields)[1]
    a, b = dataclasses.asdict(alone), dataclasses.asdict(after)
    assert np.array_equal(a.pop("identifiable_k"), b.pop("identifiable_k"))
    assert a == b
    # the strength is the weakest contradiction in multiples of the thresholds: the run is
    # identifiable iff it exceeds 1
    for lab in (alone, after):
        assert lab.identifiable == (lab.strength > 1.0) and not np.isnan(lab.strength)
