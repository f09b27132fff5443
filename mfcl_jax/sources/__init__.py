"""Every input as one record: a ``Recording`` (floor plan + ``ScanSequence`` + optional
``GroundTruth``)."""

from mfcl_jax.sources.dataset import Dataset, load_dataset
from mfcl_jax.sources.dataset_write import write_dataset
from mfcl_jax.sources.recording import GroundTruth, Recording
from mfcl_jax.sources.sequence import (
    ScanSequence,
    from_bag,
    from_carmen,
    from_dataset,
)

__all__ = [
    "Dataset",
    "load_dataset",
    "write_dataset",
    "GroundTruth",
    "Recording",
    "ScanSequence",
    "from_bag",
    "from_carmen",
    "from_dataset",
]
