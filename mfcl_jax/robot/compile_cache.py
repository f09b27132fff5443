"""JAX's on-disk compilation cache for the ``mfcl`` command.

The front-end and decision kernels take 10-30 s to compile and the same seconds again in every
new process. With the cache on, a later run of the same shapes loads the compiled code from
disk instead. Where: ``$MFCL_CACHE_DIR`` when set (``off`` disables the cache), else
``$XDG_CACHE_HOME/mfcl_jax/jax`` (default ``~/.cache/mfcl_jax/jax``). JAX prunes nothing:
delete the folder to reclaim its space. The cache is trusted code: keep it private to the user
(JAX's own warning); the folder is created mode 0700.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["cache_dir", "enable_cache", "MIN_COMPILE_S"]

# Every compilation is written. JAX's default (only those over 1 s) leaves out the ~70 small
# eager computations of a run (host-side array set-up), each 10-50 ms to compile again: about
# 1 s of a warm start, more than reading them back costs.
MIN_COMPILE_S = 0.0


def cache_dir() -> Path | None:
    """The cache folder from the environment (``None``: disabled by ``MFCL_CACHE_DIR=off``)."""
    env = os.environ.get("MFCL_CACHE_DIR")
    if env is not None:
        return None if env.strip().lower() in ("", "off", "none", "0") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "mfcl_jax" / "jax"


def enable_cache(path: Path | None = None) -> Path | None:
    """Turns the persistent compilation cache on (at ``path``, default ``cache_dir()``).

    Idempotent; a second call with another folder switches to it. A folder that cannot be
    created leaves the cache off with a warning (the run itself does not depend on it).

    Returns:
        The folder in use, or ``None`` when the cache is off.
    """
    import warnings

    import jax
    from jax.experimental.compilation_cache import compilation_cache as cc

    path = cache_dir() if path is None else Path(path)
    if path is not None:
        try:
            path.mkdir(parents=True, exist_ok=True, mode=0o700)
        except OSError as e:
            warnings.warn(
                f"{path}: compilation cache off, cannot create the folder ({e.strerror}); "
                "set MFCL_CACHE_DIR to a writable folder",
                stacklevel=2,
            )
            path = None
    want = None if path is None else str(path)
    if jax.config.jax_compilation_cache_dir != want:
        jax.config.update("jax_compilation_cache_dir", want)
        # JAX opens the cache on the first compilation; another folder needs a fresh start.
        cc.reset_cache()
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_S)
    return path
