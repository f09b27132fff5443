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
    """The CLI turns JAX's on-disk compilation cache on: keep it inside the test session (not
    in the user's ~/.cache), shared by every test that runs ``mfcl``."""
    path = tmp_path_factory.mktemp("jax-cache")
    old = os.environ.get("MFCL_CACHE_DIR")
    os.environ["MFCL_CACHE_DIR"] = str(path)
    yield path
    if old is None:
        os.environ.pop("MFCL_CACHE_DIR", None)
    else:
        os.environ["MFCL_CACHE_DIR"] = old
