"""Issue 29, item 2: units and frames checked: non-unit quaternions, millimetre scans (dataset
folders and CARMEN logs), plan and scans of different scales.

Each test fails on the code before the issue: quaternions were read as if unit; scans were
never checked for units.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from mfcl_jax.io import DataError, read_carmen, read_tum
from mfcl_jax.io.errors import DataWarning
from mfcl_jax.io.tum import yaw_from_quat
from mfcl_jax.sources import from_carmen, load_dataset
from tests._inputs import T0, _dataset, _plan, _quiet, _scans

# ---------------------------------------------------------------- quaternions


def _tum_lines(yaw_deg, scale):
    q = scale * np.array(
        [0, 0, math.sin(math.radians(yaw_deg) / 2), math.cos(math.radians(yaw_deg) / 2)]
    )
    return [f"{T0 + i} {i} 0 0 {q[0]:.9g} {q[1]:.9g} {q[2]:.9g} {q[3]:.9g}" for i in range(3)]


def test_quaternion_scaled_by_2_warns_and_gives_the_right_yaw(tmp_path):
    path = tmp_path / "o.tum"
    path.write_text("\n".join(["# t x y z qx qy qz qw"] + _tum_lines(84.0, 2.0)) + "\n")
    with pytest.warns(DataWarning) as rec:
        _, poses = read_tum(path)
    np.testing.assert_allclose(np.degrees(poses[:, 2]), 84.0, atol=1e-6)  # not 123 deg
    msg = str(rec[0].message)
    assert f"{path}:2: quaternion norm 2 differs from 1" in msg and "3 of 3" in msg
    assert "normalised" in msg and len(rec) == 1
    assert abs(math.degrees(yaw_from_quat([0, 0, 2 * 0.669130606, 2 * 0.743144825])) - 84) < 1e-6


def test_quaternion_within_tolerance_is_quiet(tmp_path):
    path = tmp_path / "o.tum"
    path.write_text("\n".join(_tum_lines(30.0, 1.0005)) + "\n")
    _, poses = _quiet(read_tum, path)
    np.testing.assert_allclose(np.degrees(poses[:, 2]), 30.0, atol=1e-6)


@pytest.mark.parametrize("scale", [0.0, 1e-8])
def test_degenerate_quaternion_refused(tmp_path, scale):
    path = tmp_path / "o.tum"
    lines = _tum_lines(30.0, 1.0)
    lines[1] = " ".join(lines[1].split()[:4] + [f"{scale * v:.9g}" for v in (0, 0, 0.5, 0.8)])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"o\.tum:2: degenerate quaternion .* norm"):
        read_tum(path)


# ---------------------------------------------------------------- units


def test_millimetre_scans_refused_naming_file_and_median(tmp_path):
    out = _dataset(tmp_path, scans=_scans(20, k=1000.0), plan=_plan())
    with pytest.raises(DataError) as e:
        load_dataset(out)
    msg = str(e.value)
    assert str(out / "scans" / "1000.0037.pcd") in msg and "millimetres" in msg
    assert re.search(r"median range \d{4} over the first 20 scans", msg)
    assert "expects scans in metres" in msg


def test_plan_and_scans_of_different_scales_refused(tmp_path):
    out = _dataset(tmp_path)
    with pytest.raises(DataError) as e:
        load_dataset(out, floorplan=_plan(1000.0))
    msg = str(e.value)
    assert "plan x1000" in msg and "disagree in scale" in msg and "8150 x 4150 units" in msg
    assert str(out / "scans") in msg and "both in metres" in msg
    assert len(_quiet(load_dataset, out, floorplan=_plan(3.0))) == 20  # a larger building


def _flaser(t, readings, x=0.0):
    r = " ".join(f"{v:g}" for v in readings)
    return f"FLASER {len(readings)} {r} {x} 0 0 {x} 0 0 {t} host {t}\n"


def test_carmen_millimetres_refused_and_odometry_through_timesync(tmp_path):
    good = tmp_path / "g.log"
    good.write_text("".join(_flaser(1.0 + i, [2.0, 3.0, 4.0], x=i) for i in range(4)))
    log = _quiet(read_carmen, good)
    seq = from_carmen(log)
    np.testing.assert_array_equal(seq.odometry[:, 0], [0, 1, 2, 3])
    with pytest.raises(DataError, match=r"g\.log: 3 odometry poses for 4 FLASER lines"):
        from_carmen(log, odometry=np.zeros((3, 3)), source=str(good))
    mm = tmp_path / "mm.log"
    mm.write_text("".join(_flaser(1.0 + i, [2000.0, 3000.0, 4000.0]) for i in range(4)))
    with pytest.raises(DataError) as e:
        read_carmen(mm)
    assert f"{mm}:1: scan ranges look like millimetres" in str(e.value)
    assert "median range 3000" in str(e.value)


def test_a_carmen_log_against_a_plan_of_another_scale_is_refused(tmp_path, capsys):
    """``mfcl localize --carmen`` checks the plan's scale against the scans' as a dataset
    folder does (here a plan far smaller than what the scans see)."""
    from mfcl_jax.cli import main
    from mfcl_jax.floorplan.geojson_write import save_geojson

    log = tmp_path / "g.log"
    log.write_text("".join(_flaser(1.0 + i, [2.0, 3.0, 4.0] * 60, x=0.1 * i) for i in range(6)))
    plan = save_geojson(_plan(0.01), tmp_path / "plan_small.geojson")  # 8 cm: scans see past it
    out = tmp_path / "d.jsonl"
    rc = main(["localize", "--carmen", str(log), "--floorplan", str(plan), "--out", str(out),
               "--quiet"])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "disagree in scale" in err and str(plan) in err, err
    assert not out.exists()
