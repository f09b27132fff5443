"""Decision layer: anchors, feasibility gate, top-1 consensus, lattice, building symmetries,
alias probe, states."""

from mfcl_jax.decision.anchors import candidate_anchors, per_run, sanitize
from mfcl_jax.decision.consensus import champions, group, leader_groups
from mfcl_jax.decision.evaluate import (
    RunInputs,
    batch_inputs,
    evaluate,
    evaluate_run,
    policy_names,
    to_frame,
)
from mfcl_jax.decision.gate import consistency_at, prefix_table, rooms_spanned
from mfcl_jax.decision.lattice import KIND_NAMES, detect
from mfcl_jax.decision.maps import DecisionMaps, decision_maps, pad_maps
from mfcl_jax.decision.policies import BASELINES, OURS_VARIANTS, Variants, baselines, variants
from mfcl_jax.decision.probe import probe
from mfcl_jax.decision.state import (
    AMBIGUOUS,
    COMMIT,
    DEFER,
    REASONS,
    STATE_NAMES,
    DecisionParams,
    Decisions,
    decide_prefix,
)
from mfcl_jax.decision.stream import Decision, SelectiveInitializer
from mfcl_jax.decision.symmetry import rotational_motions

__all__ = [
    "AMBIGUOUS",
    "BASELINES",
    "COMMIT",
    "DEFER",
    "KIND_NAMES",
    "OURS_VARIANTS",
    "REASONS",
    "STATE_NAMES",
    "Decision",
    "DecisionParams",
    "Decisions",
    "DecisionMaps",
    "SelectiveInitializer",
    "Variants",
    "baselines",
    "candidate_anchors",
    "champions",
    "consistency_at",
    "decide_prefix",
    "detect",
    "evaluate",
    "batch_inputs",
    "RunInputs",
    "evaluate_run",
    "decision_maps",
    "group",
    "leader_groups",
    "pad_maps",
    "per_run",
    "policy_names",
    "prefix_table",
    "probe",
    "rooms_spanned",
    "rotational_motions",
    "sanitize",
    "to_frame",
    "variants",
]
