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
