"""The decision layer's thresholds (``DecisionParams``) and the knobs a lane may vary.

Every field is a traced leaf, so a sweep over thresholds never recompiles. The knobs
(``KNOBS``) are read only after the shared part of a decision (``rule.finish``, the
baselines): lanes of one evaluation may differ in them and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["DecisionParams", "KNOBS", "check_sets"]

KNOBS = ("b_min", "delta_min", "confidence_ratio", "support_ratio", "cert_margin")


@dataclass(frozen=True)
class DecisionParams:
    """Decision-layer thresholds (paper Table I defaults). Every field is a traced leaf.

    Angles are in radians. ``score_floor`` drops candidates (and defers when every score is
    below it); ``confidence_ratio`` and ``support_ratio`` parametrise the baselines.
    ``recent`` is how many of the winner's most recent champions are averaged into the
    reported anchor ``T*`` (``<= 0``: all of them, the paper's ``T*``); see ``consensus``.
    Beyond the paper: ``cert_margin`` (a knob) is the verification-score advantage by which a
    window contradicts or favours an explanation and ``cert_sigma`` the score's kernel width
    (``certify``); ``drift_xy`` (fraction of the distance) and ``drift_theta`` (rad per metre)
    widen the grouping tolerances with the distance travelled between two champions' windows
    (``consensus``): an odometry of that quality keeps one place's anchors in one group.
    """

    delta_xy: float = 1.5
    delta_theta: float = float(np.deg2rad(18.0))
    b_min: float = 3.0
    delta_min: float = 2.0
    sigma_max: float = 3.0
    tau_c: float = 0.50
    n_max: float = 3.0
    gamma: float = 0.075
    eps_t: float = 2.5
    eps_theta: float = float(np.deg2rad(12.0))
    score_floor: float = 0.0
    confidence_ratio: float = 1.2
    support_ratio: float = 1.5
    recent: float = 3.0
    cert_margin: float = 0.05
    cert_sigma: float = 0.07
    drift_xy: float = 0.02
    drift_theta: float = float(np.deg2rad(0.1))

    def replace(self, **kw) -> DecisionParams:
        return replace(self, **kw)

    def as_arrays(self) -> DecisionParams:
        """Leaves as float32 JAX scalars (what kernels expect)."""
        return DecisionParams(**{f.name: jnp.float32(getattr(self, f.name)) for f in fields(self)})


jax.tree_util.register_dataclass(
    DecisionParams, data_fields=[f.name for f in fields(DecisionParams)], meta_fields=[]
)


def check_sets(params: list[DecisionParams]) -> None:
    """Threshold sets of one evaluation: finite, and differing only in ``KNOBS``."""
    names = [f.name for f in fields(DecisionParams)]
    for p in params:
        for n in names:
            v = float(getattr(p, n))
            if not np.isfinite(v):
                raise ValueError(f"DecisionParams: non-finite {n}={getattr(p, n)!r}")
            if n not in KNOBS and v != float(getattr(params[0], n)):
                raise ValueError(
                    f"DecisionParams sets may differ only in {KNOBS}; "
                    f"{n}={getattr(p, n)!r} differs from {getattr(params[0], n)!r}"
                )
