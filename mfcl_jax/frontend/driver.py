"""The one front-end driver: submaps of any number of buildings -> candidates.

Every consumer (study, benchmark, ``mfcl localize``) registers through ``FrontEnd``. A
building's features are padded to a shape bucket (raster sides rounded up to ``multiple``
cells, room and corner capacities to powers of two), so buildings of similar size share one
compilation; the buildings given at construction share ONE bucket, the smallest that holds
them all (the study's scenes: one compilation). Features are built per building on demand
and dropped after use (hundreds of buildings never sit in memory at once). Submaps are
registered in chunks of ``chunk`` submaps of one building per call: the building's features
are shared by the chunk (no per-submap copy of the rasters), and each compiled function is
reused for every chunk, building and run of its bucket.
"""

from __future__ import annotations

import time

import jax
import numpy as np

from mfcl_jax.background import Pending
from mfcl_jax.frontend import params as fe_params
from mfcl_jax.frontend import plan as fe_plan
from mfcl_jax.frontend import registration
from mfcl_jax.frontend.candidates import Candidates, no_candidates
from mfcl_jax.windows.arrays import SubmapBatch, pad_submaps
from mfcl_jax.windows.padding import pack

__all__ = ["FrontEnd"]


def _pow2(n: int, minimum: int) -> int:
    out = minimum
    while out < n:
        out *= 2
    return out


class FrontEnd:
    """Registers submaps against a fixed list of floor plans.

    Args:
        floorplans: the ``Floorplan`` of every building (index = building id); these share one
            shape bucket, buildings ``add``-ed later get their own.
        params: ``FrontendParams`` (static: a change recompiles).
        chunk: submaps per compiled call (the robot streams with ``chunk=1``).

    Attributes:
        compile_s, run_s: seconds spent compiling and running so far (compile apart).
    """

    def __init__(
        self, floorplans=(), params: fe_params.FrontendParams | None = None, chunk=16, multiple=128
    ):
        self.floorplans = list(floorplans)
        self.params = params or fe_params.FrontendParams()
        self.chunk = int(chunk)
        self.multiple = int(multiple)
        self._fn = jax.jit(
            lambda sub, feats: registration.register(sub, feats, self.params),
            compiler_options=fe_params.COMPILER_OPTIONS,
        )
        self._shared = self._bucket(self.floorplans) if self.floorplans else None
        self._n_shared = len(self.floorplans)
        self._compiled: dict = {}
        self._feats: dict[int, fe_plan.FloorplanFeatures] = {}
        self.compile_s = 0.0
        self.run_s = 0.0

    def add(self, floorplan) -> int:
        """Adds a building; returns its index."""
        self.floorplans.append(floorplan)
        return len(self.floorplans) - 1

    def _bucket(self, floorplans) -> dict:
        """``build_features`` shape arguments of the bucket holding ``floorplans``."""
        kw = fe_plan.common_shape(floorplans, multiple=self.multiple)
        # Coarse buckets: a benchmark adds hundreds of buildings; each new bucket compiles.
        kw["n_rooms"] = _pow2(kw["n_rooms"], 32)
        # Every submap corner is paired with every plan corner slot: no wider than needed.
        kw["corner_capacity"] = _pow2(max(len(fp.corners[0]) for fp in floorplans), 256)
        return kw

    def features(self, b: int) -> fe_plan.FloorplanFeatures:
        """Features of building ``b`` in its shape bucket (cached until ``release``)."""
        if b not in self._feats:
            kw = self._shared if b < self._n_shared else self._bucket([self.floorplans[b]])
            self._feats[b] = fe_plan.build_features(self.floorplans[b], self.params, **kw)
        return self._feats[b]

    def release(self, b: int | None = None) -> None:
        """Drops cached features (of building ``b``, or all)."""
        if b is None:
            self._feats.clear()
        else:
            self._feats.pop(b, None)

    @staticmethod
    def _key(sub: SubmapBatch, feats) -> tuple:
        return (sub.points.shape, feats.sdf4.shape, feats.corner_pos.shape, feats.rasters.n_rooms)

    def prepare(self, n_points: int, building: int = 0) -> None:
        """Starts compiling, in a background thread (``background.Pending``), the call that
        registers chunks of submaps of ``n_points`` points (a ``windows.pack`` capacity) in
        building ``building``'s bucket; a ``register`` of that shape then waits for it instead
        of compiling, one of any other shape compiles as usual."""
        sub = pad_submaps(pack([], capacity=int(n_points)).submaps, n=self.chunk)  # no submaps
        feats = self.features(int(building))
        key = self._key(sub, feats)
        if key not in self._compiled:
            self._compiled[key] = Pending(lambda: self._fn.lower(sub, feats).compile(),
                                          "mfcl-compile")  # fmt: skip

    def _call(self, sub: SubmapBatch, feats) -> Candidates:
        key = self._key(sub, feats)
        if key not in self._compiled or isinstance(self._compiled[key], Pending):
            t0 = time.perf_counter()
            c = self._compiled.get(key)  # a Pending from ``prepare``, or nothing yet
            c = c.result() if c is not None else self._fn.lower(sub, feats).compile()
            self._compiled[key] = c
            self.compile_s += time.perf_counter() - t0
        t0 = time.perf_counter()
        out = jax.block_until_ready(self._compiled[key](sub, feats))
        self.run_s += time.perf_counter() - t0
        return jax.tree.map(np.asarray, out)

    def register(self, submaps: SubmapBatch, building, progress=None, keep=False) -> Candidates:
        """Candidates of every submap.

        Args:
            submaps: host ``SubmapBatch`` (``N`` rows, any mix of buildings).
            building: ``(N,)`` building index of each submap.
            progress: optional callable ``progress(n_done)`` after every chunk.
            keep: keep the features cached afterwards (streaming); else they are released.

        Returns:
            ``Candidates`` with leading axis ``N`` (host arrays), in the input order.
        """
        sub = registration.sanitize_submaps(jax.tree.map(np.asarray, submaps))
        building = np.asarray(building, np.int64).reshape(-1)
        empty = no_candidates(sub.n, self.params.J)
        pose, score, mask, reason = empty.pose, empty.score, empty.mask, empty.reason
        done = 0
        for b in np.unique(building):
            rows = np.flatnonzero(building == b)
            feats = self.features(int(b))
            for a in range(0, len(rows), self.chunk):
                idx = rows[a : a + self.chunk]
                part = jax.tree.map(lambda x, i=idx: np.asarray(x)[i], sub)
                c = self._call(pad_submaps(part, n=self.chunk), feats)
                k = len(idx)
                pose[idx], score[idx], mask[idx], reason[idx] = (
                    c.pose[:k],
                    c.score[:k],
                    c.mask[:k],
                    c.reason[:k],
                )
                done += k
                if progress is not None:
                    progress(done)
            if not keep:
                self.release(int(b))
        return Candidates(pose, score, mask, reason)
