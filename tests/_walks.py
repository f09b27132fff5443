"""Two walks the early-commit tests share (``test_uniqueness``, ``test_grid``): one that only
one place in the building explains, one that four congruent rooms explain alike."""

import numpy as np

from mfcl_jax import se2
from mfcl_jax.sim.synthetic import PITCH, make_run, row_of_rooms, walk


def _truth_only(k, y):
    return [(y, 1.0)]


def _shifted_too(k, y):
    """The truth and its copy one room along, scored alike (as a congruent row gives)."""
    return [(y, 1.0), (np.asarray(se2.compose(np.array([PITCH, 0.0, 0.0]), y)), 1.0)]


def unique_walk(anchor, n_windows: int, n_cands: int):
    """``(fp, run)``: rooms of three different lengths and a walk there and back through all
    of them (one place fits); windows share scans with the two before them, as a step of
    ``d_s / 3`` cuts them, so the count needs windows 0, 3 and 6 (scan-disjoint)."""
    fp = row_of_rooms(widths=(PITCH, 9.0, 5.5))
    there_and_back = [[1.5, 1.5], [6.0, 1.5], [6.0, 3.5], [11.0, 2.5], [18.0, 2.5], [11.0, 2.5],
                      [6.0, 3.5], [1.5, 3.5]]  # fmt: skip
    run = make_run(walk(there_and_back), anchor, n_windows, _truth_only, J=n_cands, fp=fp)
    run["window_start"] = np.concatenate([[0, 0, 0], run["window_end"][:-3] + 1]).astype(np.int32)
    return fp, run


def congruent_walk(anchor, n_windows: int, n_cands: int):
    """``(fp, run)``: a loop inside the second of four congruent rooms."""
    fp = row_of_rooms()
    traj = walk([[2.0, 1.2], [5.0, 1.2], [5.0, 4.0], [2.0, 4.0], [2.0, 1.2]])
    traj[:, 0] += PITCH
    return fp, make_run(traj, anchor, n_windows, _shifted_too, J=n_cands, fp=fp)


FIELDS = (256, 512)  # the search fields' shape of both walks' buildings: one program for both


def early_state(fp, ours, n_img: int = 0):
    """The layer before the first window on ``fp`` for lanes ``ours`` (no baselines, no rival
    search), with the plan's search fields: ``(state, (maps, fields, params, lanes, spec))``."""
    import jax
    import jax.numpy as jnp

    from mfcl_jax.decision import decision_maps, layer
    from mfcl_jax.decision.maps import pad_maps
    from mfcl_jax.decision.rivals import rival_fields
    from mfcl_jax.sim.synthetic import GRID
    from tests._layer import CAPS, lanes_of

    p, lanes, spec = lanes_of(None, ours=ours, baselines=False)
    maps = jax.tree.map(jnp.asarray, pad_maps(decision_maps(fp), GRID, 4, n_motions=8,
                                              n_offsets=32))  # fmt: skip
    fields = jax.tree.map(jnp.asarray, rival_fields(fp, shape=FIELDS))
    state = layer.init(maps, p.as_arrays(), CAPS, jax.tree.map(jnp.asarray, lanes), spec,
                       fields, n_img)  # fmt: skip
    return state, (maps, fields, p, lanes, spec)
