"""Every input as one record: a ``Recording`` (floor plan + ``ScanSequence`` + optional
``GroundTruth``)."""

from mfcl_jax.sources.recording import GroundTruth, Recording
from mfcl_jax.sources.sequence import (
    ScanSequence,
    from_bag,
    from_carmen,
    from_dataset,
    keyframes,
)

__all__ = [
    "GroundTruth",
    "Recording",
    "ScanSequence",
    "from_bag",
    "from_carmen",
    "from_dataset",
    "keyframes",
]
