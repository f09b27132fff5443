"""The early-commit lanes as a person meets them: ``mfcl localize --early-commit ALPHA|grid``
picks the lane and the robot builds it, and the test's ratio (or the grid's margin) is
written to the decisions file and shown on status lines as ``L=``."""

from __future__ import annotations

import json
import math

import pytest

from mfcl_jax.cli import build_parser
from mfcl_jax.io import DataError
from mfcl_jax.io.decisions import decision_line
from mfcl_jax.robot import records, status

OLD = {"k": 1, "t": 3.5, "state": "DEFER", "anchor": None, "symmetry": None, "tau": None,
       "B1": 1, "B2": 0, "margin": 1}  # fmt: skip


def test_early_commit_selects_the_uniqueness_lane_of_its_alpha(capsys):
    """``--early-commit ALPHA`` runs the uniqueness lane of that error rate (the flag's
    choices are the lanes' rates); no flag runs ``ours``; anything else is refused."""
    from mfcl_jax.cli.common import localize_params
    from mfcl_jax.cli.localize import EARLY_COMMIT_ALPHAS
    from mfcl_jax.decision.lanes import UNIQUE_LANES
    from mfcl_jax.robot.localizer import LocalizeParams

    assert sorted(EARLY_COMMIT_ALPHAS) == sorted(UNIQUE_LANES)
    parse = build_parser().parse_args
    p = localize_params(parse(["localize", "d", "--early-commit", "0.001"]))
    assert p.policy == "ours_unique" and p.unique_llr == pytest.approx(math.log(1e3))
    assert localize_params(parse(["localize", "d", "--early-commit", "1e-1"])).policy == (
        "ours_unique_a1"
    )
    p = localize_params(parse(["localize", "d"]))
    assert p.policy == "ours" and p.unique_llr is None
    p = localize_params(parse(["localize", "d", "--early-commit", "grid"]))
    assert p.policy == "ours_grid" and p.unique_llr == 4.0  # the grid lane, at its margin
    with pytest.raises(SystemExit):
        parse(["localize", "d", "--early-commit", "0.05"])
    assert "'0.05' is neither 'grid' nor one of" in capsys.readouterr().err
    with pytest.raises(ValueError, match="policy='paper', expected one of"):
        LocalizeParams(policy="paper")
    # the robot builds its one lane from the policy: the test on, at log(1 / alpha)
    from mfcl_jax.robot.localizer import Localizer
    from mfcl_jax.sim.scenes import symmetric_bays

    fp = symmetric_bays().floorplan
    for args, unique, llr in ((["--early-commit", "1e-2"], True, math.log(1e2)), ([], False, 0),
                              (["--early-commit", "grid"], False, 0)):  # fmt: skip
        loc = Localizer(fp, localize_params(parse(["localize", "d", *args])))
        lanes, spec = loc._init[3], loc._init[4]  # (maps, params, caps, lanes, spec, ...)
        assert spec.unique == unique and len(spec.names) == 1
        assert float(lanes.unique_llr[0]) == pytest.approx(llr, rel=1e-6)
        assert spec.grid == ("grid" in args) and float(lanes.grid_margin[0]) == 4.0 * spec.grid


def test_the_uniqueness_ratio_is_written_and_shown():
    """A uniqueness lane's line holds ``unique: {llr, needed}`` (null where the test did not
    run, "inf" / "-inf" where nothing competed / a veto held); the status line shows it as
    ``L=ratio/threshold``; a bad entry is named."""
    assert records.unique_entry(3.35291, 6.9078) == {"llr": 3.3529, "needed": 6.9078}
    assert records.unique_entry(float("nan"), 2.3026)["llr"] is None
    assert records.unique_entry(float("inf"), 2.3026)["llr"] == "inf"
    assert records.unique_entry(float("-inf"), 2.3026)["llr"] == "-inf"
    base = dict(OLD, pose=None, reason="unsaturated", alternatives=None)
    lines = [status.status_line(dict(base, unique=records.unique_entry(v, 6.9078)))
             for v in (3.35291, float("nan"), float("-inf"), float("inf"))]  # fmt: skip
    assert [ln.split("margin=1 ")[1] for ln in lines] == [
        "L=3.35/6.91]", "L=-/6.91]", "L=vetoed/6.91]", "L=inf/6.91]"
    ]  # fmt: skip
    assert "L=" not in status.status_line(base)  # ours: no test, nothing shown
    line = decision_line(dict(base, unique=records.unique_entry(float("inf"), 6.9078)))
    assert json.loads(line)["unique"] == {"llr": "inf", "needed": 6.9078}
    for bad, words in (({"llr": 1.0}, "expected {llr, needed}"),
                       ({"llr": "big", "needed": 2.3}, "unique.llr='big'"),
                       ({"llr": 1.0, "needed": 0.0}, "unique.needed=0.0")):  # fmt: skip
        with pytest.raises(DataError, match="decision #0") as e:
            decision_line(dict(base, unique=bad), "decision #0")
        assert words in str(e.value)
