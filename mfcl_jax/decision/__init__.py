"""Decision layer: anchors, feasibility gate, top-1 consensus, lattice, building symmetries,
alias probe, certification, commit machine; one pure ``update`` per window (``layer``)."""

from mfcl_jax.decision.anchors import candidate_anchors, sanitize
from mfcl_jax.decision.frame import to_frame
from mfcl_jax.decision.history import Caps
from mfcl_jax.decision.inputs import RunInputs, run_inputs
from mfcl_jax.decision.lanes import (
    BASELINES,
    OURS_VARIANTS,
    STRICT_IOU,
    Lanes,
    LaneSpec,
    make_lanes,
)
from mfcl_jax.decision.layer import LayerState, WindowEvidence, advance, init, update
from mfcl_jax.decision.maps import DecisionMaps, decision_maps
from mfcl_jax.decision.outcome import AMBIGUOUS, COMMIT, DEFER, REASONS, STATE_NAMES, Decision
from mfcl_jax.decision.params import KNOBS, DecisionParams
from mfcl_jax.decision.runs import decide_runs

__all__ = [
    "AMBIGUOUS",
    "BASELINES",
    "COMMIT",
    "DEFER",
    "KNOBS",
    "OURS_VARIANTS",
    "REASONS",
    "STATE_NAMES",
    "STRICT_IOU",
    "Caps",
    "Decision",
    "DecisionMaps",
    "DecisionParams",
    "LaneSpec",
    "Lanes",
    "LayerState",
    "RunInputs",
    "WindowEvidence",
    "advance",
    "candidate_anchors",
    "decide_runs",
    "decision_maps",
    "init",
    "make_lanes",
    "run_inputs",
    "sanitize",
    "to_frame",
    "update",
]
