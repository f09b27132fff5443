"""mfcl_jax: Move First, Commit Later -- selective LiDAR-to-BIM global initialization in JAX."""

__version__ = "0.1.0"
