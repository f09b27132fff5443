"""Safe output: targets checked before the run (inputs, links, devices, folders, permissions),
atomic writes with the umask's permissions, and the CLI's refusals (exit 2, one message,
no partial output, inputs untouched)."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
from shapely.geometry import box

from mfcl_jax.cli import main
from mfcl_jax.floorplan import Door, Floorplan, Room, save_geojson
from mfcl_jax.io import DataError, atomic_write, check_output
from mfcl_jax.sources import write_dataset


def _plan() -> Floorplan:
    walls = np.array(
        [[[0, 0], [8, 0]], [[8, 0], [8, 4]], [[8, 4], [0, 4]], [[0, 4], [0, 0]]], float
    )
    return Floorplan(
        walls=walls,
        thickness=0.15,
        rooms=(Room("a", box(0, 0, 4, 4)), Room("b", box(4, 0, 8, 4))),
        doors=(Door(np.array([[4, 1.5], [4, 2.5]]), ("a", "b")),),
    )


@pytest.fixture
def umask():
    def set_mask(m):
        os.umask(m)

    old = os.umask(0o022)
    yield set_mask
    os.umask(old)


def _mode(p) -> int:
    return stat.S_IMODE(os.stat(p).st_mode)


def test_atomic_write_uses_the_umask(tmp_path, umask):
    assert _mode(atomic_write(tmp_path / "a.txt", "x")) == 0o644
    umask(0o027)
    assert _mode(atomic_write(tmp_path / "b.txt", b"x")) == 0o640
    umask(0o022)
    ds = write_dataset(
        tmp_path / "ds", _plan(), [0.0, 1.0], [np.ones((3, 2))] * 2, np.zeros((2, 3))
    )
    assert _mode(ds) == 0o755 and _mode(ds / "odometry.tum") == 0o644


def test_check_output_refusals(tmp_path):
    src = tmp_path / "in.geojson"
    src.write_text("{}")
    (tmp_path / "hard.geojson").hardlink_to(src)
    cases = [
        (dict(path=src, inputs=[src]), "output is an input of this run"),
        (dict(path=tmp_path / "hard.geojson", inputs=[src]), "output is an input of this run"),
        (dict(path=tmp_path / "x" / ".." / "in.geojson", inputs=[src]), "is an input"),
        (dict(path=tmp_path / "scans" / "o.txt", inputs=[tmp_path / "scans"]), "inside the input"),
        (dict(path=tmp_path, inputs=[src], folder=True), "holds the input"),
        (dict(path=tmp_path), "output is a folder, expected a file name"),
        (dict(path=src, folder=True), "output is a file, expected a folder name"),
        (dict(path=src / "o.txt"), "is not a folder"),
    ]
    (tmp_path / "scans").mkdir()
    (tmp_path / "x").mkdir()
    for kw, words in cases:
        with pytest.raises(DataError) as e:
            check_output(**kw)
        assert str(kw["path"]) in str(e.value) and words in str(e.value), (kw, str(e.value))
    assert src.read_text() == "{}"
    assert check_output(tmp_path / "new" / "deeper" / "o.txt", inputs=[src]).name == "o.txt"


def test_links_and_devices_refused(tmp_path):
    target = tmp_path / "target.txt"
    target.write_text("keep")
    link = tmp_path / "link.txt"
    link.symlink_to(target)
    dangling = tmp_path / "dangling.txt"
    dangling.symlink_to(tmp_path / "nowhere.txt")
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    for p, words in ((link, "symbolic link"), (dangling, "symbolic link"), (fifo, "FIFO")):
        with pytest.raises(DataError, match=words):
            check_output(p)
        with pytest.raises(DataError, match=words):
            atomic_write(p, "x")
    with pytest.raises(DataError, match="device"):
        check_output("/dev/null")
    assert target.read_text() == "keep" and link.is_symlink()
    assert not (tmp_path / "nowhere.txt").exists()


def test_permission_errors_are_messages(tmp_path, monkeypatch):
    real_access = os.access
    locked = tmp_path / "locked"
    locked.mkdir()
    monkeypatch.setattr(
        os, "access", lambda p, m: False if str(p) == str(locked) else real_access(p, m)
    )
    with pytest.raises(
        DataError, match=r"locked.*permission denied: folder .*locked is not writable"
    ):
        check_output(locked / "o.txt")
    monkeypatch.setattr(os, "access", real_access)

    def deny(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", deny)
    with pytest.raises(DataError, match=r"o\.txt: cannot write \(Permission denied\)"):
        atomic_write(tmp_path / "o.txt", "x")
    assert [p.name for p in tmp_path.iterdir()] == ["locked"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(DataError, match="permission denied"):
            check_output(ro / "o.txt")
    finally:
        ro.chmod(0o755)


# ---------------------------------------------------------------------- the CLI
@pytest.fixture
def dataset(tmp_path):
    return write_dataset(
        tmp_path / "ds", _plan(), [0.0, 1.0], [np.ones((3, 2))] * 2, np.zeros((2, 3))
    )


@pytest.fixture
def no_work(monkeypatch):
    """The checks must come before any loading: loading fails the test."""

    def boom(*a, **k):
        raise AssertionError("the run started before its output was checked")

    import mfcl_jax.cli.inputs
    import mfcl_jax.floorplan.load
    import mfcl_jax.sources.simulated

    monkeypatch.setattr(mfcl_jax.cli.inputs, "load_input", boom)
    monkeypatch.setattr(mfcl_jax.floorplan.load, "load_floorplan", boom)
    monkeypatch.setattr(mfcl_jax.sources.simulated, "simulate_dataset", boom)


def _refused(argv, capsys, *words):
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mfcl: error:") and "Traceback" not in err and err.count("\n") == 1
    for w in words:
        assert str(w) in err, err


def _snapshot(folder):
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_cli_localize_out_checked_first(dataset, tmp_path, capsys, no_work):
    before = _snapshot(tmp_path)
    odo = dataset / "odometry.tum"
    _refused(["localize", dataset, "--out", odo], capsys, odo, "output is an input")
    scan = next((dataset / "scans").iterdir())
    _refused(["localize", dataset, "--out", scan], capsys, scan, "inside the input folder")
    plan = dataset / "floorplan.geojson"
    _refused(["localize", dataset, "--out", plan], capsys, plan, "output is an input")
    link = tmp_path / "dec.jsonl"
    link.symlink_to(odo)
    _refused(["localize", dataset, "--out", link], capsys, link, "symbolic link")
    link.unlink()
    assert _snapshot(tmp_path) == before


def test_cli_floorplan_show_out_checked_first(tmp_path, capsys, no_work):
    from PIL import Image

    plan = save_geojson(_plan(), tmp_path / "p.geojson")
    _refused(["floorplan", "show", plan, "--out", plan], capsys, plan, "output is an input")
    Image.fromarray(np.full((20, 20), 254, np.uint8)).save(tmp_path / "m.png")
    (tmp_path / "m.yaml").write_text("image: m.png\nresolution: 0.1\norigin: [0, 0, 0]\n")
    before = _snapshot(tmp_path)
    _refused(
        ["floorplan", "show", tmp_path / "m.yaml", "--out", tmp_path / "m.png"],
        capsys,
        "m.png",
        "output is an input",
    )
    _refused(["floorplan", "show", plan, "--out", tmp_path], capsys, "output is a folder")
    assert _snapshot(tmp_path) == before


def test_cli_simulate_out_checked_first(tmp_path, capsys, no_work):
    plan = save_geojson(_plan(), tmp_path / "p.geojson")
    wp = tmp_path / "work" / "wp.csv"
    wp.parent.mkdir()
    wp.write_text("1,1\n3,1\n")
    before = _snapshot(tmp_path)
    _refused(
        ["simulate", "--floorplan", plan, "--trajectory", wp, "--out", tmp_path / "work",
         "--overwrite"],
        capsys,
        "holds the input",
    )  # fmt: skip
    _refused(
        ["simulate", "--floorplan", plan, "--trajectory", wp, "--out", plan, "--overwrite"],
        capsys,
        "output is a file, expected a folder",
    )
    assert _snapshot(tmp_path) == before


def test_cli_permission_error_is_a_message(tmp_path, capsys, monkeypatch):
    plan = save_geojson(_plan(), tmp_path / "p.geojson")

    def deny(*a, **k):
        raise PermissionError(13, "Permission denied", str(tmp_path / "o.png"))

    monkeypatch.setattr(os, "replace", deny)
    _refused(["floorplan", "show", plan, "--out", tmp_path / "o.png"], capsys, "o.png", "denied")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.geojson"]
