"""The outputs of the two sides of ``benchmarks/versions.py`` compared: the sweep's tables
(content, the stage timings apart) and the decisions (``k``, ``state``) of every window."""

from __future__ import annotations

import gzip
import pathlib


def count_lines(paths) -> int:
    return sum(sum(1 for _ in open(p)) for p in paths)


def read_table(path: pathlib.Path) -> bytes:
    if path.name.endswith(".gz"):
        with gzip.open(path) as f:
            return f.read()
    return path.read_bytes()


def compare_tables(a: pathlib.Path, b: pathlib.Path) -> list[str]:
    """Names (relative paths) of the .csv / .csv.gz files that differ or exist on one side."""

    def tables(d):
        return {
            str(p.relative_to(d)) for p in d.rglob("*")
            if p.name.endswith((".csv", ".csv.gz")) and not p.name.startswith("timings")
        }  # fmt: skip

    ta, tb = tables(a), tables(b)
    diff = [f"{n} (old only)" for n in sorted(ta - tb)]
    diff += [f"{n} (new only)" for n in sorted(tb - ta)]
    diff += [n for n in sorted(ta & tb) if read_table(a / n) != read_table(b / n)]
    return diff


def compare_states(old_files, new_files) -> str:
    """The last run's decisions, old against new: the (k, state) of every window."""
    import json

    def states(files):
        out = []
        for i, f in enumerate(files):  # the i-th file of each side: the same dataset
            if not f.exists():
                out.append((i, "missing"))
                continue
            out += [(i, d.get("k"), d.get("state")) for d in map(json.loads, open(f))]
        return out

    a, b = states(old_files), states(new_files)
    if a == b:
        return f"same state at every window ({len(b)} windows)"
    pairs = [(x, y) for x, y in zip(a, b, strict=False) if x != y]
    n = len(pairs) + abs(len(a) - len(b))
    first = ""
    if pairs and len(pairs[0][0]) == 3 and len(pairs[0][1]) == 3:
        (i, k, so), (_, _, sn) = pairs[0]
        first = f", first: {new_files[i].stem} k={k} old {so}, new {sn}"
    return f"states differ at {n} of {max(len(a), len(b))} windows{first}"
