"""Peer localizers: what a robot would run instead of our selective initializer.

``mcl``: AMCL-like global localization (a particle filter over the floor plan's free space),
fed the same keyframe scans and odometry as our layer and read at the same window ends.
"""

from mfcl_jax.peers.mcl import MCLTrace, commits, make_mcl, run_mcl, trace_count
from mfcl_jax.peers.mcl_batch import MCLBatch, pad_batch, prepare_mcl_inputs
from mfcl_jax.peers.mcl_params import MCLParams

__all__ = [
    "MCLBatch",
    "pad_batch",
    "MCLParams",
    "MCLTrace",
    "commits",
    "make_mcl",
    "prepare_mcl_inputs",
    "run_mcl",
    "trace_count",
]
