"""What the generalisation benchmark runs: families, seeds, policies, fault axes.

Every name and number is checked here, before any work starts, and a bad one is an error
naming the option and the value (``BenchmarkError``).

Sources of runs ("families"):

* procedural building families (``sim.families``), ``walks`` walks per building and
  ``seeds`` buildings per family;
* ``ifc:<model>``: the shared IFC models with ``ifc_walks`` random door-to-door tours each
  (per seed);
* ``log:<name>`` / ``bag:intel``: windows of the real laser logs against occupancy maps built
  without the window's own scans, ``log_windows`` windows each;
* ``tower:<kind>`` (not in the default run): the tower family (``sim.families.tower``), four
  storeys, one walk per storey, each against the whole building's stacked plan; a commit on
  a place several congruent storeys share names no storey and is scored false.

Fault axes (``faults``) re-run a base set of procedural runs (``fault_seeds`` seeds x the
first walk of every procedural family) at every level of the axis; ``near_symmetric`` has its
own base set (``NEAR_SYMMETRIC``: exactly symmetric buildings whose plan gets one stub).
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = [
    "BenchmarkError",
    "BenchmarkConfig",
    "PROCEDURAL",
    "TOWERS",
    "IFC_MODELS",
    "LOGS",
    "FAULTS",
    "NEAR_SYMMETRIC",
    "POLICIES",
    "OPT_IN",
    "validate",
]

PROCEDURAL = ("plain", "bays", "offices", "corridor", "hall", "ring", "rotational", "mirror")
TOWERS = ("tower:typical", "tower:one_room", "tower:rotated")
IFC_MODELS = {
    "office_a": ("ifc/Office_A_20110811.ifc", "Level 1"),
    "duplex": ("ifc/Duplex_A_20110907_Architecture.ifc", "Level 1"),
    "fzk_haus": ("ifc/AC20-FZK-Haus.ifc", "Erdgeschoss"),
}
LOGS = ("intel", "freiburg-101", "orebro", "seattle")
# axis -> levels (the first level of the numeric axes is the nominal setting)
FAULTS = {
    "drift": (0.005, 0.01, 0.02, 0.03),  # odometry translation drift, fraction of distance
    "yaw_drift": (0.1, 0.25, 0.5),  # deg per metre
    "clutter": (0.0, 0.15, 0.3, 0.5),  # extra furniture, fraction of the floor area
    "dropout": (0.02, 0.2, 0.4, 0.6),  # fraction of beams lost
    "range_noise": (0.02, 0.035, 0.05),  # m
    "as_built": ("missing_wall", "extra_partition", "moved_door"),
    "scale": (1.0, 1.01, 1.02),  # floor-plan scale error
    "restart": (0.35, 0.5, 0.65),  # odometry restart at this fraction of the walk
    "plan": ("no_doors", "rooms_only"),  # the plan without door features; rooms only
    "latency": (0.05, 0.15, 0.3),  # s by which the odometry lags the scans
    # one stub breaks an exactly symmetric building's plan; built as drawn, not, twice, moved
    "near_symmetric": ("stub_built", "stub_unbuilt", "stub_twin", "stub_moved"),
}
# the near-symmetric axis's own base set: per family, the first seeds whose plan has an exact
# self-motion and a room for the stub (``sim.families.nearsym``), walks A and B of each
NEAR_SYMMETRIC = {"rotational": 3, "bays": 3}
# every policy is run unless ``policies=`` says otherwise
POLICIES = (
    "ours",
    "paper",
    "no_probe",
    "consensus_only",
    "ours_b2_d1",
    "ours_b4_d2",
    "single_shot",
    "support",
    "confidence",
    "gate_only",
    "mcl",
)

# run only when ``policies=`` names them, the early-commit lanes: ``ours_unique*``, the
# uniqueness test at five error rates (the trade-off of risk against metres), ``ours_grid``,
# which commits on the evidence grid's margin (``decision.grid``), and ``ours_grid_off``, which
# records the margin and never commits on it (the calibration reads it). They cost most of
# the decision stage (a path search or a grid per window while open); ``results/
# benchmark_early`` holds their run (``docs/benchmark.md``)
OPT_IN = ("ours_unique", "ours_unique_a1", "ours_unique_a2", "ours_unique_a4",
          "ours_unique_a6", "ours_grid", "ours_grid_off")  # fmt: skip


class BenchmarkError(ValueError):
    """A benchmark option that cannot be run; the message names the option and value."""


@dataclass
class BenchmarkConfig:
    """The benchmark (Hydra schema; ``conf/benchmark.yaml`` fills it).

    Attributes:
        families: sources of runs (see the module docstring).
        seeds: buildings per procedural family (and tours per IFC model multiplier).
        walks: walks per procedural building.
        ifc_walks: random tours per IFC model and seed.
        log_windows: windows per real log (and the Intel bag).
        log_length: metres of travel per log window.
        policies: systems under test (our variants, the baselines, ``mcl``).
        faults: fault axes to run (``all`` for every axis, empty for none).
        fault_seeds: seeds of the fault base set.
        d_s: window length (m).
        mcl_particles: particles of the filter peer.
        out: output folder.
        cache: cache folder for floor plans, maps and labels (``""``: no cache).
        figures: draw figures.
        progress: print progress.
    """

    families: list[str] = field(
        default_factory=lambda: [
            *PROCEDURAL,
            *(f"ifc:{m}" for m in IFC_MODELS),
            *(f"log:{n}" for n in LOGS),
            "bag:intel",
        ]
    )
    seeds: int = 4
    walks: int = 3
    ifc_walks: int = 2
    log_windows: int = 4
    log_length: float = 45.0
    policies: list[str] = field(default_factory=lambda: list(POLICIES))
    faults: list[str] = field(default_factory=lambda: ["all"])
    fault_seeds: int = 1
    d_s: float = 6.0
    mcl_particles: int = 4096
    out: str = "results/benchmark"
    cache: str = "~/.cache/mfcl_jax"
    figures: bool = True
    progress: bool = True


def _bad(option: str, value, known=None) -> BenchmarkError:
    tail = f"; known: {', '.join(map(str, known))}" if known is not None else ""
    return BenchmarkError(f"benchmark: {option}={value!r} is not valid{tail}")


def validate(cfg: BenchmarkConfig) -> BenchmarkConfig:
    """Checks every option; returns ``cfg`` with ``faults=["all"]`` expanded."""
    known = [*PROCEDURAL, *(f"ifc:{m}" for m in IFC_MODELS), *(f"log:{n}" for n in LOGS)]
    known += ["bag:intel", *TOWERS]
    for f in cfg.families:
        if f not in known:
            raise _bad("families", f, known)
    if not cfg.families:
        raise _bad("families", [], known)
    for name in ("seeds", "walks", "ifc_walks", "log_windows", "fault_seeds"):
        v = getattr(cfg, name)
        if not isinstance(v, int) or isinstance(v, bool) or v <= 0:
            raise _bad(name, v)
    if not cfg.log_length >= 20.0:
        raise BenchmarkError(
            f"benchmark: log_length={cfg.log_length!r} is too short: a log window needs at "
            "least 20 m of travel (a few submap windows)"
        )
    if not cfg.d_s > 0 or cfg.d_s > cfg.log_length / 2:
        raise _bad("d_s", cfg.d_s)
    for p in cfg.policies:
        if p not in POLICIES + OPT_IN:
            raise _bad("policies", p, POLICIES + OPT_IN)
    if not cfg.policies:
        raise _bad("policies", [], POLICIES)
    faults = list(FAULTS) if list(cfg.faults) == ["all"] else list(cfg.faults)
    for f in faults:
        if f not in FAULTS:
            raise _bad("faults", f, ["all", *FAULTS])
    cfg.faults = faults
    if cfg.mcl_particles < 64:
        raise _bad("mcl_particles", cfg.mcl_particles)
    return cfg
