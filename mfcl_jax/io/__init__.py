"""Input/output: TUM trajectories, PCD scans, dataset folders, ROS bags, CARMEN logs and
decision logs."""

from mfcl_jax.io.bag import BagScans, read_bag
from mfcl_jax.io.carmen import CarmenLog, read_carmen
from mfcl_jax.io.dataset import Dataset, load_dataset, write_dataset
from mfcl_jax.io.decisions import read_decisions, write_decisions
from mfcl_jax.io.errors import DataError
from mfcl_jax.io.pcd import read_pcd, write_pcd
from mfcl_jax.io.tum import read_tum, write_tum

__all__ = [
    "BagScans",
    "CarmenLog",
    "DataError",
    "Dataset",
    "load_dataset",
    "read_bag",
    "read_carmen",
    "read_decisions",
    "read_pcd",
    "read_tum",
    "write_dataset",
    "write_decisions",
    "write_pcd",
    "write_tum",
]
