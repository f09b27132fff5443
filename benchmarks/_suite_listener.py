"""A pytest plugin for ``benchmarks/suite.py``: what each test spent compiling.

Loaded with ``-p benchmarks._suite_listener``; it listens to JAX's monitoring events (tracing,
lowering, XLA's compilation with the program's name, disk-cache reads) and to pytest's phase
timings, attributes each to the test running at the time, and writes one JSON file per worker
into ``$MFCL_SUITE_OUT``. In-process only: what an ``mfcl`` or ``experiments`` subprocess of a
test compiles is in that test's wall time, not in its compile columns.
"""

from __future__ import annotations

import collections
import json
import os
import threading
from pathlib import Path

import jax.monitoring
import pytest

_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace_s",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower_s",
    "/jax/core/compile/backend_compile_duration": "compile_s",
    "/jax/compilation_cache/cache_retrieval_time_sec": "cache_read_s",
}
_lock = threading.Lock()
_current = {"test": "(collection)"}
_tests: dict = collections.defaultdict(collections.Counter)
_programs: dict = collections.defaultdict(collections.Counter)


def _listen(event: str, seconds: float, **kw) -> None:
    col = _EVENTS.get(event)
    if col is None:
        return
    with _lock:  # background compilations report from their own threads
        test = _current["test"]
        _tests[test][col] += seconds
        _tests[test][col.replace("_s", "_n")] += 1
        if col == "compile_s":
            row = _programs[(test, str(kw.get("fun_name", "?")))]
            row["seconds"] += seconds
            row["n"] += 1


jax.monitoring.register_event_duration_secs_listener(_listen)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _current["test"] = item.nodeid
    yield


def pytest_runtest_logreport(report):
    with _lock:
        _tests[report.nodeid]["wall_s"] += report.duration


def pytest_sessionfinish(session):
    out = os.environ.get("MFCL_SUITE_OUT")
    if not out:
        return
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    data = {
        "worker": worker,
        "tests": {t: dict(c) for t, c in _tests.items()},
        "programs": [{"test": t, "program": p, **c} for (t, p), c in _programs.items()],
    }
    Path(out).mkdir(parents=True, exist_ok=True)
    (Path(out) / f"{worker}.json").write_text(json.dumps(data))
