"""Experiment entry points (thin: the logic lives in mfcl_jax)."""
