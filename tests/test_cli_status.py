"""What a person reads: status lines (the robot's pose, reasons in words), the help and
``docs/status.md`` text, the decisions file's ``pose`` / ``reason``, progress only where a
person watches, and the compilation cache's folder."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mfcl_jax.cli import build_parser, main
from mfcl_jax.io import DataError, read_decisions, write_decisions
from mfcl_jax.io.decisions import decision_line
from mfcl_jax.robot import records, status
from mfcl_jax.robot.progress import Progress

ROOT = Path(__file__).resolve().parents[1]

OLD = {"k": 1, "t": 3.5, "state": "DEFER", "anchor": None, "symmetry": None, "tau": None,
       "B1": 1, "B2": 0, "margin": 1}  # fmt: skip


def _commit(**kw):
    d = dict(OLD, k=11, t=48.0, state="COMMIT", B1=9, B2=1, margin=8)
    d["anchor"] = {"x": 20.0, "y": 2.0, "yaw_deg": 90.0}
    return dict(d, **kw)


# ------------------------------------------------------------------ text for a person
def test_every_reason_and_state_is_explained():
    from mfcl_jax.decision.outcome import REASONS, STATE_NAMES
    from mfcl_jax.robot.records import OTHER_STOREY

    # the layer's reasons, and the one the host edge gives (a commit on another storey)
    assert set(status.REASON_TEXT) == set(REASONS.values()) - {""} | {OTHER_STOREY}
    assert set(status.STATE_TEXT) == set(STATE_NAMES.values())
    text = status.help_text()
    for word in [*status.REASON_TEXT, *status.STATE_TEXT, "B1", "B2", "margin", "tau", "L"]:
        assert f"{word}: " in text


def test_help_epilog_keeps_its_layout(capsys):
    with pytest.raises(SystemExit):
        main(["localize", "--help"])
    out = capsys.readouterr().out
    assert status.help_text() in out  # RawDescriptionHelpFormatter: not re-wrapped
    for flag in ("--band-min", "--follow", "--idle-timeout", "--out-dir", "--progress"):
        assert flag in out


def test_docs_snippet_is_the_help_text():
    assert (ROOT / "docs" / "status.md").read_text() == status.markdown()
    assert "`winner infeasible`" in status.markdown()


def test_status_lines_read_as_the_examples():
    defer = dict(OLD, k=1, t=12.0, reason="unsaturated", pose=None)
    amb = dict(OLD, k=3, t=20.0, state="AMBIGUOUS", symmetry="translation", tau=[7.3, 0.0],
               B1=3, B2=0, margin=3, reason="", pose=None)  # fmt: skip
    commit = records.record(_commit(), (4.02, -1.4, math.radians(-2.5)), "")
    got = [status.status_line(d) for d in (defer, amb, commit)]
    assert tuple(got) == status.EXAMPLE
    multi = dict(OLD, state="AMBIGUOUS", symmetry="multimodal", reason="")
    assert "several separate places" in status.status_line(multi)
    assert "too few agreeing windows" in status.status_line(dict(OLD, state="AMBIGUOUS"))
    assert status.status_line(dict(OLD, reason="spread"), "pts=5").endswith("margin=1 pts=5]")


def test_record_gives_the_robot_pose_in_the_plan_frame():
    X = (1.0, 2.0, math.radians(30.0))
    d = records.record(_commit(), X, "", offset=(500000.0, 5e6))
    # T* = (20, 2, 90 deg): x' = 20 - 2, y' = 2 + 1, heading 120 deg; then + offset.
    assert d["pose"]["x"] == pytest.approx(500018.0, abs=1e-9)
    assert d["pose"]["y"] == pytest.approx(5000003.0, abs=1e-9)
    assert d["pose"]["yaw_deg"] == pytest.approx(120.0)
    assert d["anchor"] == {"x": 500020.0, "y": 5000002.0, "yaw_deg": 90.0}
    assert records.record(dict(OLD), X, "unsaturated") == dict(
        OLD, pose=None, reason="unsaturated", alternatives=None
    )


def test_an_ambiguous_record_lists_where_each_explanation_puts_the_robot():
    X = (1.0, 2.0, math.radians(30.0))
    amb = dict(OLD, state="AMBIGUOUS", symmetry="rotation", B1=4, B2=2, margin=2)
    best, rival = (20.0, 2.0, math.radians(90.0)), (-3.0, 0.0, math.radians(-90.0))
    d = records.record(amb, X, "competitor not ruled out", (100.0, 0.0), best=best, rival=rival)
    assert d["anchor"] is None and d["pose"] is None
    (p, q) = d["alternatives"]
    # robot pose under each anchor, A X_k, then + offset: (18, 3, 120 deg) and (-1, -1, -60 deg)
    assert (p["x"], p["y"], p["yaw_deg"]) == pytest.approx((118.0, 3.0, 120.0))
    assert (q["x"], q["y"], q["yaw_deg"]) == pytest.approx((99.0, -1.0, -60.0))
    line = status.status_line(d)
    assert "robot at (118.00, 3.00, 120 deg) or (99.00, -1.00, -60 deg)" in line, line
    assert read_decisions_line(d) == d
    # a file line lists alternatives only with AMBIGUOUS, each a full pose
    with pytest.raises(DataError, match="only an AMBIGUOUS decision lists them"):
        decision_line(dict(OLD, pose=None, reason="", alternatives=[p]))
    with pytest.raises(DataError, match=r"alternatives\[1\]=\{'x': 1.0\}, expected"):
        decision_line(dict(d, alternatives=[p, {"x": 1.0}]))
    with pytest.raises(DataError, match="expected a non-empty list or null"):
        decision_line(dict(d, alternatives=[]))


def read_decisions_line(d):
    return json.loads(decision_line(d))


@given(
    st.tuples(*[st.floats(-50, 50)] * 2, st.floats(-3.1, 3.1)),
    st.tuples(*[st.floats(-50, 50)] * 2, st.floats(-3.1, 3.1)),
)
def test_robot_pose_is_the_group_product(a, x):
    from mfcl_jax import se2

    want = np.asarray(se2.compose(np.asarray(a, np.float32), np.asarray(x, np.float32)))
    got = np.asarray(records.robot_pose(a, x))
    np.testing.assert_allclose(got[:2], want[:2], atol=2e-3)
    assert abs((got[2] - want[2] + np.pi) % (2 * np.pi) - np.pi) < 1e-5


# ------------------------------------------------------------------ the decisions file
def test_decisions_with_pose_and_reason_round_trip(tmp_path):
    rows = [dict(OLD, pose=None, reason="unsaturated", alternatives=None),
            records.record(_commit(), (0.0, 0.0, 0.0), "")]  # fmt: skip
    path = write_decisions(tmp_path / "d.jsonl", rows)
    assert read_decisions(path) == rows
    keys = list(json.loads(path.read_text().splitlines()[1]))
    assert keys[:9] == ["k", "t", "state", "anchor", "symmetry", "tau", "B1", "B2", "margin"]
    assert keys[9:] == ["pose", "reason", "alternatives"]
    old = tmp_path / "old.jsonl"  # a file written before pose and reason existed
    old.write_text(json.dumps(OLD) + "\n")
    assert read_decisions(old) == [OLD]


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(pose={"x": 1.0, "y": 2.0}), "pose={'x': 1.0, 'y': 2.0}, expected {x, y, yaw_deg}"),
        (dict(pose={"x": 1.0, "y": 2.0, "yaw_deg": float("nan")}), "non-finite value"),
        (dict(pose={"x": 1.0, "y": 2.0, "yaw_deg": 0.0}), "with state='DEFER'"),
        (dict(reason=4), "reason=4, expected a string"),
    ],
)
def test_bad_pose_or_reason_is_named(tmp_path, change, words):
    path = tmp_path / "d.jsonl"
    path.write_text(json.dumps(dict(OLD, pose=None, reason=""), allow_nan=True) + "\n")
    path.write_text(path.read_text() + json.dumps(dict(OLD, k=2, **change)) + "\n")
    with pytest.raises(DataError, match=r"d\.jsonl:2: ") as e:
        read_decisions(path)
    assert words in str(e.value)
    with pytest.raises(DataError, match="pose=None with state='COMMIT'"):
        decision_line(dict(_commit(), pose=None, reason=""))
    with pytest.raises(DataError, match="decision #0"):
        write_decisions(tmp_path / "e.jsonl", [dict(OLD, reason=None)])
    assert not (tmp_path / "e.jsonl").exists()


def test_evaluate_reads_files_with_pose(tmp_path):
    from mfcl_jax.score import decisions_frame

    path = write_decisions(tmp_path / "d.jsonl", [records.record(_commit(), (0, 0, 0), "")])
    assert decisions_frame(read_decisions(path))["x"].tolist() == [20.0]


# ------------------------------------------------------------------ progress
class _Tty(io.StringIO):
    def isatty(self):
        return True


def test_progress_is_silent_in_pipes_and_forced_by_the_flag():
    quiet = io.StringIO()
    p = Progress(None, quiet)
    with p.stage("loading"):
        pass
    p.note("hello")
    assert list(p.track(iter([1, 2, 3]), 3)) == [1, 2, 3] and quiet.getvalue() == ""
    forced = io.StringIO()
    p = Progress(True, forced)
    assert list(p.track(iter(range(3)), 3, first="compiling")) == [0, 1, 2]
    lines = forced.getvalue().splitlines()
    assert lines[0] == "mfcl: compiling ..." and lines[1].startswith("mfcl: compiling: done in")
    assert "\r" not in forced.getvalue()  # a log gets whole lines
    assert list(Progress(True, io.StringIO()).track(iter(()), 0)) == []
    with Progress(True, forced).counted("registering 3 windows", 3) as done:
        done(2)
    assert forced.getvalue().splitlines()[-1].startswith("mfcl: registering 3 windows: done")
    tty = _Tty()
    with Progress(None, tty).counted("registering", 3) as done:
        done(2)
        done(3)
    assert "registering" in tty.getvalue() and "3/3" in tty.getvalue()


def test_progress_spins_on_a_terminal():
    import time

    tty = _Tty()
    p = Progress(None, tty)
    assert p.enabled and p.animate
    with p.stage("compiling"):
        time.sleep(0.35)
    text = tty.getvalue()
    assert "\r| compiling 0 s" in text and text.endswith("s\n") and "done in 0." in text
    with pytest.raises(KeyboardInterrupt), p.stage("waiting"):
        raise KeyboardInterrupt
    assert "mfcl: waiting: stopped in" in tty.getvalue()


def test_progress_flag_reaches_simulate_and_localize():
    args = build_parser().parse_args(["simulate", "--floorplan", "p", "--trajectory", "t",
                                      "--out", "o", "--progress"])  # fmt: skip
    assert args.progress
    assert build_parser().parse_args(["localize", "d", "--progress"]).progress


# ------------------------------------------------------------------ compilation cache
def test_cache_folder_from_the_environment(monkeypatch, tmp_path):
    import jax

    from mfcl_jax.robot.compile_cache import cache_dir, enable_cache

    monkeypatch.delenv("MFCL_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "mfcl_jax" / "jax"
    monkeypatch.setenv("MFCL_CACHE_DIR", "off")
    assert cache_dir() is None
    monkeypatch.setenv("MFCL_CACHE_DIR", str(tmp_path / "c"))
    old = jax.config.jax_compilation_cache_dir  # the test session's folder
    try:
        assert enable_cache() == tmp_path / "c" and (tmp_path / "c").is_dir()
        assert jax.config.jax_compilation_cache_dir == str(tmp_path / "c")
        assert jax.config.jax_persistent_cache_min_compile_time_secs == 0.0
        blocked = tmp_path / "file"
        blocked.write_text("")
        with pytest.warns(UserWarning, match="compilation cache off"):
            assert enable_cache(blocked / "sub") is None
        assert jax.config.jax_compilation_cache_dir is None
    finally:
        monkeypatch.setenv("MFCL_CACHE_DIR", old or "off")
        enable_cache()
