"""Many datasets in one ``mfcl localize`` call: a folder of dataset folders in one batch, one
decisions file each, a summary table; refusals before anything is written."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from mfcl_jax.cli import main
from mfcl_jax.io import read_decisions
from mfcl_jax.sim.scenes import symmetric_bays

WALKS = {
    "east": [(1.0, 4.2), (3.0, 1.8), (16.0, 1.8)],
    "west": [(27.0, 1.8), (12.0, 1.8)],
}


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    from mfcl_jax.sources.simulated import simulate_dataset

    root = tmp_path_factory.mktemp("many") / "all"
    fp = symmetric_bays().floorplan
    for seed, (name, wp) in enumerate(WALKS.items()):
        simulate_dataset(fp, np.asarray(wp), root / name, seed=seed)
    return root


def _snapshot(folder):
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_folder_of_datasets_in_one_batch(folder, tmp_path, capsys, monkeypatch):
    """Three datasets in chunks of at most two: chunks of 2 and 1, the second padded to the
    first, so one compiled program decides both; ``zeast`` (a copy of ``east``, alone in the
    padded chunk) decides as ``east`` does. Within a memory budget the first chunk passes,
    the rest is decided one recording at a time, to the same decisions."""
    from mfcl_jax.decision.runs import TRACES
    from mfcl_jax.drive import batch as driver

    data, out = tmp_path / "data", tmp_path / "out"
    for name in WALKS:
        shutil.copytree(folder / name, data / name)
    shutil.copytree(folder / "east", data / "zeast")
    monkeypatch.setattr(driver, "CHUNK", 2)
    before = TRACES["scan_runs"]
    assert main(["localize", str(data), "--out-dir", str(out)]) == 0
    assert TRACES["scan_runs"] - before <= 1
    cap = capsys.readouterr()
    text = cap.out
    names = ["east", "west", "zeast"]
    assert sorted(p.name for p in out.iterdir()) == [f"{n}.jsonl" for n in names]
    table = text[text.index("dataset  windows") :].splitlines()
    assert table[0].split() == ["dataset", "windows", "first", "commit", "k", "final", "state"]
    decs = {n: read_decisions(out / f"{n}.jsonl") for n in names}
    for name, line in zip(names, table[2:5], strict=True):
        d = decs[name]
        first = next((x["k"] for x in d if x["state"] == "COMMIT"), "-")
        assert line.split() == [name, str(len(d)), str(first), d[-1]["state"]]
        assert f"{data / name}: " in text and all("pose" in x and "reason" in x for x in d)
    assert decs["zeast"] == decs["east"]
    assert "memory: " in cap.err and "at the peak, budget" in cap.err  # reported
    # a budget the first chunk passes: the chunks after it are halved (one recording each),
    # the decisions are the same, and it says so
    again = tmp_path / "again"
    assert main(["localize", str(data), "--out-dir", str(again), "--max-memory", "1M",
                 "--quiet", "--progress"]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "above the budget of 0.00 GiB: 1 recordings per chunk from now on" in err
    assert "(2 chunks; 2 chunks above it)" in err
    assert {n: read_decisions(again / f"{n}.jsonl") for n in names} == decs
    assert main(["localize", str(data), "--out-dir", str(again), "--max-memory", "lots"]) == 2
    assert "--max-memory: 'lots' is not a memory size; give e.g. 6G" in capsys.readouterr().err
    # (that the batch decides as a robot does, one window at a time, is
    # tests/test_rivals.py::test_robot_and_batch_search_at_the_same_windows_and_agree)


def test_many_refusals_write_nothing(folder, tmp_path, capsys):
    def fails(argv, *words):
        assert main([str(a) for a in argv]) == 2
        err = capsys.readouterr().err
        assert err.startswith("mfcl: error:") and err.count("\n") == 1 and "Traceback" not in err
        for w in words:
            assert str(w) in err, err

    before = _snapshot(folder)
    east, west = folder / "east", folder / "west"
    out = tmp_path / "out"
    fails(["localize", east, west, "--out", tmp_path / "d.jsonl"], "names one file but 2 datasets")
    twin = tmp_path / "twin" / "east"
    shutil.copytree(east, twin)
    fails(["localize", east, twin, "--out-dir", out], twin, "same dataset name as", east)
    fails(["localize", east, west, "--out-dir", east / "scans"], "inside the input folder")
    fails(["localize", east, west, "--lidar-offset", "1,0,0"], east, "already the sensor pose")
    broken = tmp_path / "broken"
    shutil.copytree(west, broken)
    (broken / "odometry.tum").write_text("0 1 2 3\n")
    fails(["localize", east, broken, "--out-dir", out], broken / "odometry.tum", "8 columns")
    assert not out.exists() and _snapshot(folder) == before


def test_the_one_batch_path_cuts_groups_as_they_come(folder):
    """``drive.register`` (the study's, the benchmark's and this command's path): a lazy group
    is cut only once the group before it is, the front-end's call compiles for the asked
    capacity before the first cut, and the result is that of cutting, packing and registering
    by hand."""
    from mfcl_jax import windows as W
    from mfcl_jax.drive.register import register
    from mfcl_jax.frontend.driver import FrontEnd
    from mfcl_jax.sources import ScanSequence
    from mfcl_jax.sources.dataset import load_dataset

    data = [load_dataset(folder / n) for n in WALKS]
    seqs = [ScanSequence(d.times, d.scans, d.odometry, str(d.folder)) for d in data]
    fe = FrontEnd([data[0].floorplan], chunk=16)
    p, cap = W.WindowParams(), W.bucket(W.WindowParams().capacity, 256)
    said = []

    def groups():
        for s in seqs:
            said.append("made")
            yield [(s, p, 0)]

    def cut(group, wins):
        assert group[0][0] is seqs[len([x for x in said if x == "cut"])]
        said.append("cut")
        assert len(fe._compiled) == 1  # the call for ``cap``, compiling since before the cut

    reg = register(groups(), fe, capacity=cap, on_cut=cut)
    assert said == ["made", "cut", "made", "cut"]
    assert reg.batch.runs.n_runs == 2 and [len(w) for w in reg.windows] == [
        len(W.cut(s, p)) for s in seqs
    ]
    by_hand = W.pack([(s, W.cut(s, p), 0) for s in seqs], capacity=cap)
    np.testing.assert_array_equal(reg.batch.submaps.points, by_hand.submaps.points)
    got = FrontEnd([data[0].floorplan], chunk=16).register(by_hand.submaps, by_hand.building)
    np.testing.assert_array_equal(reg.cands.pose, got.pose)
    np.testing.assert_array_equal(reg.cands.score, got.score)
