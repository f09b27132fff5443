"""Test configuration: strict dtype promotion and CPU-friendly hypothesis settings."""

import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402
import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

jax.config.update("jax_numpy_dtype_promotion", "strict")

# "ci" (the default) draws the same examples on every run, so a landing gate is never decided
# by chance; HYPOTHESIS_PROFILE=explore draws fresh ones (run it to hunt for new failures and
# pin what it finds with @example).
_common = dict(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("ci", derandomize=True, **_common)
settings.register_profile("explore", **_common)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session", autouse=True)
def _compilation_cache(tmp_path_factory):
    """JAX's on-disk compilation cache for the whole test session (not the user's ~/.cache):
    shared by both xdist workers, by every in-process compilation and by every ``mfcl``
    subprocess, so a kernel compiled by one test is read back by the next that needs the same
    shapes (the suite's time is mostly compilation)."""
    from mfcl_jax.robot.compile_cache import enable_cache

    root = tmp_path_factory.getbasetemp()
    # under xdist each worker has its own basetemp (.../popen-gwN): share the parent's folder
    path = (root.parent if root.name.startswith("popen-gw") else root) / "jax-cache"
    path.mkdir(exist_ok=True)
    old = os.environ.get("MFCL_CACHE_DIR")
    os.environ["MFCL_CACHE_DIR"] = str(path)
    # every Python subprocess (experiments, benchmark jobs) reads the same cache
    os.environ["JAX_COMPILATION_CACHE_DIR"] = str(path)
    os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0"
    enable_cache(path)
    yield path
    if old is None:
        os.environ.pop("MFCL_CACHE_DIR", None)
    else:
        os.environ["MFCL_CACHE_DIR"] = old
