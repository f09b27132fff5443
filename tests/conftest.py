"""Test configuration: strict dtype promotion, CPU-friendly hypothesis settings, how the two
xdist workers share the files (``GROUPS``) and the session's JAX compilation cache."""

import os
from pathlib import Path

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

# How the two xdist workers share the suite (``pytest_xdist_make_scheduler`` below). The suite's
# time is mostly compiling the layer, the front-end and the robot's step; a worker compiles a
# program once and keeps it in memory, so files that compile the same programs run on one
# worker, one after another (JAX's disk cache, shared by both, only skips XLA's part, and only
# once the other worker has finished writing). Every other file is a group of its own. Groups
# are handed out heaviest first: the weights are a serial run's seconds per group
# (``pytest -n 0 --durations=0``, rounded); a new file counts 1 until it is added here.
GROUPS = {
    "decision": (
        "test_decision_layer", "test_decision_invariance", "test_decision_stepwise",
        "test_decision_consensus", "test_decision_rotation", "test_decision_machine",
        "test_decision_gate", "test_decision_drift", "test_uniqueness",
        "test_rivals", "test_path_llr",
    ),
    "robot": (
        "test_cli", "test_cli_3d", "test_viz", "test_viz_writer", "test_cli_segments",
        "test_cli_live", "test_cli_status", "test_cli_signals", "test_cli_inputs", "test_cli_many",
        "test_traced", "test_plan_frame", "test_safe_output", "test_input_rates",
        "test_input_units", "test_input_bags", "test_ros2_node", "test_named_failures",
    ),
    "frontend": ("test_frontend", "test_frontend_kernels", "test_frontend_driver"),
    "benchmark": ("test_benchmark", "test_benchmark_tables", "test_launcher"),
    "families": ("test_families", "test_family_symmetry", "test_family_faults"),
    "mcl": ("test_mcl", "test_mcl_model"),
}  # fmt: skip
WEIGHTS = {
    "decision": 125, "robot": 110, "benchmark": 40, "frontend": 48, "test_study": 45,
    "mcl": 35, "test_real_floorplans": 13, "families": 10, "test_sim": 8,
    "test_identifiability": 8, "test_path_bound": 18, "test_storeys": 60,
}  # fmt: skip
_GROUP_OF = {f: g for g, files in GROUPS.items() for f in files}


def _group(nodeid: str) -> str:
    stem = Path(nodeid.split("::")[0]).stem
    return _GROUP_OF.get(stem, stem)


@pytest.hookimpl(optionalhook=True)  # a hook of xdist's: absent with ``-p no:xdist``
def pytest_xdist_make_scheduler(config, log):
    """xdist's file-by-file scheduling with GROUPS as the work units (xdist's own
    ``--dist loadgroup`` reads marks into node ids, which pytest 9 no longer lets it edit)."""
    from xdist.scheduler import LoadScopeScheduling

    class GroupScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _group(nodeid)

    return GroupScheduling(config, log)


def pytest_collection_modifyitems(config, items):
    """The groups heaviest first, each group's tests in their collection order (the work
    queue keeps this order: ``--no-loadscope-reorder``)."""
    first = {}
    for i, item in enumerate(items):
        first.setdefault(_group(item.nodeid), i)
    items.sort(key=lambda it: (-WEIGHTS.get(_group(it.nodeid), 1), first[_group(it.nodeid)]))


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


# Cyclone DDS on loopback only, unicast to this machine (no multicast leaves it), in a domain
# of this test process's own so that parallel workers do not hear each other.
LOOPBACK_DDS = (
    '<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto"
    '</ParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain>'
    "</CycloneDDS>"
)


@pytest.fixture
def ros2_env(monkeypatch):
    """ROS 2 over DDS on loopback in a domain of this worker's own (``ROS_DOMAIN_ID``,
    ``CYCLONEDDS_URI``: read by the node subprocesses too); yields the domain."""
    domain = 100 + os.getpid() % 100
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK_DDS)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    yield domain
