"""The robot's step kept traced on disk, so that a warm start skips tracing it.

JAX's compilation cache (``compile_cache``) stores compiled code, but its key is the lowered
program, so every new process still traces and lowers the step first: about 3 s of a warm
``mfcl localize`` start before the first status line. ``Traced`` exports the step once
(``jax.export``: the lowered program, serialised) next to the compilation cache and, in a
later process, reads it back instead of tracing; the compilation cache then supplies the
compiled code. The file's key is a digest of the package's source files, the JAX version,
the inputs' structure, shapes and dtypes and the static settings, so a changed program is
never read back. Without a cache folder (``MFCL_CACHE_DIR=off``) it is a plain ``jax.jit``.

``prepare`` traces (or reads back) and compiles the step for given inputs in a background
thread, so that a robot's first window need not wait for all of it: the robot prepares its
step while the LiDAR odometry runs over the first metres, and the first call waits for what
is left.
"""

from __future__ import annotations

import hashlib
import os
import uuid
import warnings
from pathlib import Path

import jax
import numpy as np

from mfcl_jax.background import Pending

__all__ = ["Traced", "source_digest"]

_DIGEST: list[str] = []


def source_digest() -> str:
    """SHA-256 of every source file of the package and of the JAX version (memoised)."""
    if not _DIGEST:
        root = Path(__file__).resolve().parents[1]
        h = hashlib.sha256(f"jax {jax.__version__}".encode())
        for p in sorted(root.rglob("*.py")):
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
        _DIGEST.append(h.hexdigest())
    return _DIGEST[0]


def _specs(leaves) -> tuple:
    return tuple(jax.ShapeDtypeStruct(np.shape(x), jax.numpy.result_type(x)) for x in leaves)


class Traced:
    """``fn`` jitted, its traced program kept in ``folder`` (``None``: plain ``jax.jit``).

    Args:
        fn: a pure function of array pytrees (static settings bound beforehand).
        name: the file name's stem.
        folder: where the exported programs live.
        static: a string naming the static settings bound into ``fn`` (part of the key).
        out_like: ``out_like(*args)``: a pytree with the structure of ``fn``'s output (its
            leaves are ignored), so a program read back needs no trace to unflatten.
        donate_argnums, compiler_options: as ``jax.jit``'s.
    """

    def __init__(self, fn, name: str, folder: Path | None, static: str, out_like,
                 donate_argnums=(), compiler_options=None):  # fmt: skip
        self._fn, self._name, self._static, self._out_like = fn, name, static, out_like
        self._folder = None if folder is None else Path(folder) / "traced"
        self._donate = tuple(donate_argnums)
        self._options = compiler_options
        self._jit = jax.jit(fn, donate_argnums=self._donate, compiler_options=compiler_options)
        self._calls: dict = {}

    def __call__(self, *args):
        leaves, tree = jax.tree.flatten(args)
        key = (tree, _specs(leaves))
        call = self._calls.get(key)
        if call is None:
            call = self._calls[key] = self._make(args, tree, key[1], ahead=False)
        elif isinstance(call, Pending):
            call = self._calls[key] = call.result()
        return call(leaves)

    def prepare(self, *args) -> None:
        """Trace (or read back) and compile the call for inputs shaped like ``args`` in a
        background thread; the first call with such inputs waits for it (and raises what it
        raised). Inputs of another shape are prepared at their first call, as before."""
        leaves, tree = jax.tree.flatten(args)
        key = (tree, _specs(leaves))
        if key not in self._calls:
            self._calls[key] = Pending(lambda: self._make(args, tree, key[1], ahead=True))

    @property
    def n_programs(self) -> int:
        """Input structures prepared or called so far (each its own program)."""
        return len(self._calls)

    def _make(self, args, tree, specs, ahead: bool):
        """The call for inputs of this structure (compiled now if ``ahead``, else at its
        first use): read back, or exported and written; a plain jit without a folder."""
        if self._folder is None:
            if ahead:
                compiled = self._jit.lower(*args).compile()
                return lambda leaves: compiled(*jax.tree.unflatten(tree, leaves))
            return lambda leaves: self._jit(*jax.tree.unflatten(tree, leaves))
        out_tree = jax.tree.structure(self._out_like(*args))
        # which flat leaves belong to donated arguments
        counts = [len(jax.tree.leaves(a)) for a in args]
        starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
        donate = tuple(i for a in self._donate for i in range(starts[a], starts[a + 1]))
        parts = [source_digest(), self._name, self._static, str(tree), str(specs),
                 str(out_tree), repr(self._options)]  # fmt: skip
        digest = hashlib.sha256("\n".join(parts).encode()).hexdigest()[:32]
        path = self._folder / f"{self._name}-{digest}.jaxexport"
        try:
            exp = self._load(path) or self._export(tree, specs, path)
        except Exception as e:  # noqa: BLE001 - a failed cache never stops the robot
            warnings.warn(f"{path}: traced program not kept ({e}); tracing as usual",
                          stacklevel=3)  # fmt: skip
            return lambda leaves: self._jit(*jax.tree.unflatten(tree, leaves))
        # every input placed on the one device: the program read back returns arrays placed
        # there, and an input fed back from a previous call must not compile a second program
        one = jax.sharding.SingleDeviceSharding(jax.devices()[0])
        run = jax.jit(lambda *leaves: exp.call(*leaves), donate_argnums=donate,
                      in_shardings=one, out_shardings=one,
                      compiler_options=self._options)  # fmt: skip
        if ahead:
            run = run.lower(*specs).compile()
        return lambda leaves: jax.tree.unflatten(out_tree, run(*leaves))

    @staticmethod
    def _load(path: Path):
        if not path.is_file():
            return None
        try:
            return jax.export.deserialize(bytearray(path.read_bytes()))
        except Exception:  # noqa: BLE001 - a damaged file is traced again and rewritten
            return None

    def _export(self, tree, specs, path: Path):
        def flat(*leaves):
            return jax.tree.leaves(self._fn(*jax.tree.unflatten(tree, leaves)))

        exp = jax.export.export(jax.jit(flat))(*specs)
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        tmp = path.with_suffix(f".tmp{os.getpid()}-{uuid.uuid4().hex[:8]}")
        tmp.write_bytes(exp.serialize())
        tmp.replace(path)  # atomic: a concurrent reader sees the whole file or none
        return exp
