"""The speed scripts under ``benchmarks/`` still import what they use.

Nothing is run or timed: every ``benchmarks/*.py`` is parsed with ``ast`` and each import of
the project's own code (``mfcl_jax``, and the ``tests`` helpers some scripts build their
inputs from), at top level or inside a function, is resolved: ``import mfcl_jax.x.y`` must
import, and ``from mfcl_jax.x import a, b`` must import ``mfcl_jax.x`` and find ``a`` and
``b`` in it (an attribute, or a submodule as ``from ... import`` would load it). A package
refactor that leaves a script behind fails here, not when someone next wants its numbers.
"""

from __future__ import annotations

import ast
import importlib
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "benchmarks").glob("*.py"))
OWN = ("mfcl_jax", "tests", "benchmarks")


def _own(module: str | None) -> bool:
    return module is not None and module.split(".")[0] in OWN


def project_imports(path: pathlib.Path) -> list[tuple[int, str, str | None]]:
    """``(line, module, name)`` of every project import in ``path`` (``name`` None for a
    plain ``import module``)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name, None) for a in node.names if _own(a.name)]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and _own(node.module):
            out += [(node.lineno, node.module, a.name) for a in node.names]
    return sorted(out)


def _problem(module: str, name: str | None) -> str | None:
    try:
        mod = importlib.import_module(module)
    except ImportError as e:
        return f"import {module}: {type(e).__name__}: {e}"
    if name is None or name == "*" or hasattr(mod, name):
        return None
    try:  # ``from pkg import submodule`` loads the submodule
        importlib.import_module(f"{module}.{name}")
    except ModuleNotFoundError:
        return f"from {module} import {name}: {module} has no {name!r}"
    return None


def test_every_script_is_checked():
    assert len(SCRIPTS) >= 5, SCRIPTS
    assert project_imports(ROOT / "benchmarks" / "decision.py")


@pytest.mark.parametrize("path", SCRIPTS, ids=[p.name for p in SCRIPTS])
def test_benchmark_script_imports_resolve(path):
    problems = {  # a module that fails to import fails once per line, not once per name
        f"{path.name}:{line}: {msg}": None
        for line, module, name in project_imports(path)
        if (msg := _problem(module, name)) is not None
    }
    assert not problems, "\n".join(problems)


def test_suite_report_charges_compilation_to_files_and_names_the_eager_operations(tmp_path):
    """``benchmarks/suite.py`` reads the listener's per-worker files: seconds per test file
    summed over both workers, XLA seconds per program, and the eager single operations (a
    one-operation program under 0.2 s a compilation) counted apart from the real programs."""
    import json

    from benchmarks import suite

    def worker(name, tests, programs):
        (tmp_path / f"{name}.json").write_text(
            json.dumps({"worker": name, "tests": tests, "programs": programs})
        )

    a, b = "tests/test_a.py::t1", "tests/test_b.py::t2"
    worker("gw0", {a: {"wall_s": 10.0, "compile_s": 6.0, "trace_s": 1.0, "compile_n": 3}},
           [{"test": a, "program": "jit(scan_runs)", "seconds": 5.5, "n": 1},
            {"test": a, "program": "jit(add)", "seconds": 0.3, "n": 2},
            {"test": a, "program": "jit(dot)", "seconds": 0.9, "n": 1}])  # fmt: skip
    worker("gw1", {b: {"wall_s": 4.0, "compile_s": 1.0, "compile_n": 1},
                   "tests/test_a.py::t3": {"wall_s": 2.0}},
           [{"test": b, "program": "jit(add)", "seconds": 0.15, "n": 1}])  # fmt: skip
    worker("main", {a: {"wall_s": 99.0}}, [])  # the xdist controller's copy: not counted
    tests, progs = suite._frames(tmp_path)
    per_file, per_prog, md = suite.report(tests, progs, wall_s=12.0)
    assert per_file.loc["test_a.py", "wall_s"] == 12.0 and per_file.index[0] == "test_a.py"
    assert per_file.loc["test_b.py", "compile_s"] == 1.0
    assert "16 s (gw0 10 s, gw1 6 s)" in md  # the controller's copy (main) left out
    assert per_prog.loc["jit(add)", "n"] == 3
    assert per_prog.loc["jit(add)", "seconds"] == pytest.approx(0.45)
    # jit(add): 0.15 s a compilation over both tests (0.15 in each): eager; jit(dot),
    # one compilation of 0.9 s: a program, listed with the layer's
    assert "eager operations (one-operation programs under 0.2 s each) 3 compilations" in md
    listed = md.split("Programs, by XLA compile seconds")[1]
    assert "jit(scan_runs)" in listed and "jit(dot)" in listed and "jit(add)" not in listed
