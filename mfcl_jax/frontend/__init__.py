"""Registration front-end: pose Hough transform over wall corners, occupancy-aware
verification, continuous refinement; plus a CSV adapter for external front-ends."""

from mfcl_jax.frontend.csv_adapter import load_candidates_csv
from mfcl_jax.frontend.params import COMPILER_OPTIONS, FrontendParams
from mfcl_jax.frontend.plan import FloorplanFeatures, build_features, common_features
from mfcl_jax.frontend.registration import make_register, register, sanitize_submaps

__all__ = [
    "COMPILER_OPTIONS",
    "FloorplanFeatures",
    "FrontendParams",
    "build_features",
    "common_features",
    "load_candidates_csv",
    "make_register",
    "register",
    "sanitize_submaps",
]
