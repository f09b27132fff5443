"""The particle filter's input batch, padded on the host from ``Recording`` objects.

``prepare_mcl_inputs`` takes recordings (floor plan + scan sequence), the keyframes the filter
is fed and the window ends at which it is read, and pads everything to one shape: steps to a
multiple of 32, scan points to a power of two, windows to a multiple of 8, floor-plan grids to
a multiple of 32 cells with an origin per run. Padding is masked (steps, points, windows) or
inert (grid cells: far from walls, not free, not passable), so a run's result does not depend on the
batch it is padded into.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import jax
import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.windows.arrays import bucket

__all__ = ["MCLBatch", "pad_batch", "prepare_mcl_inputs"]

# Distance read in padded grid cells: beyond any cap ``max_dist``.
_FAR = 1.0e3


@dataclass(frozen=True)
class MCLBatch:
    """Padded filter inputs; ``R`` runs, ``T`` steps, ``P`` points, ``K`` windows, ``H x W`` grid.

    Attributes:
        scans: ``(R, T, P, 2)`` float32 keyframe scan points in the sensor frame.
        mask: ``(R, T, P)`` bool, valid points.
        odom: ``(R, T, 3)`` float32 keyframe odometry poses in L (padded by the last pose).
        step_mask: ``(R, T)`` bool, real steps.
        window_end: ``(R, K)`` int32 step index of each window's last keyframe (0 if padded).
        window_mask: ``(R, K)`` bool, real windows.
        dist: ``(R, H, W)`` float32 distance to the nearest wall solid (m).
        free: ``(R, H, W)`` bool, cells where a particle may start (``passable`` and at least
            the clearance from a wall).
        passable: ``(R, H, W)`` bool, inside the building and not in a wall.
        origin: ``(R, 2)`` float32 grid origin of each run.
        run_id: ``(R,)`` uint32 stable run identifier (CRC-32 of the recording name): with the
            seed it fixes the run's random stream.
        res: grid cell size (m), static.
    """

    scans: np.ndarray
    mask: np.ndarray
    odom: np.ndarray
    step_mask: np.ndarray
    window_end: np.ndarray
    window_mask: np.ndarray
    dist: np.ndarray
    free: np.ndarray
    passable: np.ndarray
    origin: np.ndarray
    run_id: np.ndarray
    res: float = 0.10

    @property
    def n_runs(self) -> int:
        return int(self.scans.shape[0])


jax.tree_util.register_dataclass(
    MCLBatch,
    data_fields=[
        "scans",
        "mask",
        "odom",
        "step_mask",
        "window_end",
        "window_mask",
        "dist",
        "free",
        "passable",
        "origin",
        "run_id",
    ],
    meta_fields=["res"],
)


def _round_up(n: int, m: int) -> int:
    return max(m, -(-n // m) * m)


def _even_pick(n_valid: int, n: int) -> np.ndarray:
    """Ranks of ``n`` points spread evenly over ``n_valid`` (as ``mcl_model.select_beams``)."""
    if n_valid <= n:
        return np.arange(n_valid)
    return np.floor((np.arange(n) + 0.5) * n_valid / n).astype(int)


def prepare_mcl_inputs(
    recordings,
    window_ends,
    keyframe_indices=None,
    *,
    res: float = 0.10,
    clearance: float = 0.2,
    max_points: int | None = None,
    crop_radius: float | None = None,
) -> MCLBatch:
    """Pads recordings into one ``MCLBatch``.

    Args:
        recordings: ``Recording`` objects (their floor plan and scan sequence are used; the
            ground truth is not).
        window_ends: per recording, ``(K_r,)`` indices into its keyframe list of the keyframes
            at which the filter is read (a window's last keyframe), non-decreasing.
        keyframe_indices: per recording, ``(M_r,)`` increasing scan indices fed to the filter;
            ``None`` feeds every scan.
        res: floor-plan raster cell (m).
        clearance: particles start only in cells inside the building, not in a wall, and at
            least this far from one (m): a robot's centre cannot be closer.
        max_points: keep at most this many points per scan, picked evenly by rank (the filter's
            own pick, so ``max_points = n_beams`` gives the same result as keeping all; it
            bounds the batch's memory). ``None`` keeps all.
        crop_radius: drop points farther than this from the sensor (m) before picking;
            ``SubmapParams.crop_radius`` (10 m) feeds the filter the evidence our windows keep.
            ``None`` keeps the LiDAR's full range, as a robot running AMCL would.

    Returns:
        ``MCLBatch`` of NumPy arrays.

    Raises:
        DataError: an index out of range, no window, or a floor plan without free space.
    """
    recordings = list(recordings)
    if crop_radius is not None and not crop_radius > 0:
        raise DataError(f"prepare_mcl_inputs: crop_radius must be > 0, got {crop_radius!r}")
    if not recordings:
        raise DataError("prepare_mcl_inputs: no recordings")
    if len(window_ends) != len(recordings):
        raise DataError(
            f"prepare_mcl_inputs: {len(window_ends)} window lists for {len(recordings)} recordings"
        )
    if keyframe_indices is None:
        keyframe_indices = [np.arange(len(r.seq)) for r in recordings]
    rasters, kfs, wes = {}, [], []
    for rec, kf, we in zip(recordings, keyframe_indices, window_ends, strict=True):
        kf = np.asarray(kf, np.int64).reshape(-1)
        we = np.asarray(we, np.int64).reshape(-1)
        n = len(rec.seq)
        if len(kf) == 0 or kf.min() < 0 or kf.max() >= n or np.any(np.diff(kf) <= 0):
            raise DataError(f"{rec.name}: keyframe indices must increase within [0, {n})")
        if len(we) == 0:
            raise DataError(f"{rec.name}: no window ends")
        if we.min() < 0 or we.max() >= len(kf) or np.any(np.diff(we) < 0):
            raise DataError(
                f"{rec.name}: window ends must be non-decreasing in [0, {len(kf)}), got "
                f"{we.min()}..{we.max()}"
            )
        kfs.append(kf)
        wes.append(we)
        if id(rec.floorplan) not in rasters:
            r = rec.floorplan.rasterize(res)
            passable = r.inside & ~r.wall
            free = passable & (r.dist >= clearance)
            if not free.any():
                raise DataError(
                    f"{rec.floorplan.source}: no free cell at >= {clearance} m from the walls"
                )
            rasters[id(rec.floorplan)] = (r, free, passable)

    R = len(recordings)
    T = _round_up(max(len(k) for k in kfs), 32)
    K = _round_up(max(len(w) for w in wes), 8)
    scans_r = []
    for rec, kf in zip(recordings, kfs, strict=True):
        pts = []
        for i in kf:
            p = np.asarray(rec.seq.scans[i], np.float64).reshape(-1, 2)
            keep = np.all(np.isfinite(p), axis=1)
            if crop_radius is not None:
                keep &= np.einsum("ij,ij->i", p, p) <= crop_radius**2
            p = p[keep]
            if max_points is not None:
                p = p[_even_pick(len(p), max_points)]
            pts.append(p)
        scans_r.append(pts)
    P = bucket(max(len(p) for pts in scans_r for p in pts), minimum=64)
    H = _round_up(max(r[0].shape[0] for r in rasters.values()), 32)
    W = _round_up(max(r[0].shape[1] for r in rasters.values()), 32)

    scans = np.zeros((R, T, P, 2), np.float32)
    mask = np.zeros((R, T, P), bool)
    odom = np.zeros((R, T, 3), np.float32)
    step_mask = np.zeros((R, T), bool)
    window_end = np.zeros((R, K), np.int32)
    window_mask = np.zeros((R, K), bool)
    dist = np.full((R, H, W), _FAR, np.float32)
    free = np.zeros((R, H, W), bool)
    passable = np.zeros((R, H, W), bool)
    origin = np.zeros((R, 2), np.float32)
    run_id = np.zeros(R, np.uint32)
    for r, (rec, kf, we, pts) in enumerate(zip(recordings, kfs, wes, scans_r, strict=True)):
        m = len(kf)
        for t, p in enumerate(pts):
            scans[r, t, : len(p)] = p
            mask[r, t, : len(p)] = True
        x = rec.seq.odometry[kf]
        odom[r, :m] = x
        odom[r, m:] = x[-1]
        step_mask[r, :m] = True
        window_end[r, : len(we)] = we
        window_mask[r, : len(we)] = True
        ras, fr, pa = rasters[id(rec.floorplan)]
        h, w = ras.shape
        dist[r, :h, :w] = ras.dist
        free[r, :h, :w] = fr
        passable[r, :h, :w] = pa
        origin[r] = ras.origin
        run_id[r] = zlib.crc32(rec.name.encode()) & 0x7FFFFFFF
    return MCLBatch(
        scans=scans,
        mask=mask,
        odom=odom,
        step_mask=step_mask,
        window_end=window_end,
        window_mask=window_mask,
        dist=dist,
        free=free,
        passable=passable,
        origin=origin,
        run_id=run_id,
        res=float(res),
    )


def pad_batch(batch: MCLBatch, *, runs: int = 8, steps: int = 128, windows: int = 16,
              grid: int = 128) -> MCLBatch:  # fmt: skip
    """``batch`` padded to coarse shape buckets, so that many batches share one compilation.

    Runs are padded to a multiple of ``runs`` by copies of run 0 (drop their results: the first
    ``batch.n_runs`` rows are the real runs), steps, windows and grid sides to multiples of
    ``steps``, ``windows`` and ``grid`` (masked or inert, as in ``prepare_mcl_inputs``); the
    real runs' results do not change.
    """
    R, T, P = batch.mask.shape
    K = batch.window_mask.shape[1]
    H, W = batch.dist.shape[1:]
    R2, T2, K2 = _round_up(R, runs), _round_up(T, steps), _round_up(K, windows)
    H2, W2 = _round_up(H, grid), _round_up(W, grid)
    take = np.concatenate([np.arange(R), np.zeros(R2 - R, np.int64)])

    def pad(a, shape, value=0):
        a = np.asarray(a)[take]
        return np.pad(a, [(0, n - m) for n, m in zip(shape, a.shape, strict=True)],
                      constant_values=value)  # fmt: skip

    odom = pad(batch.odom, (R2, T2, 3))
    odom[:, T:] = odom[:, T - 1 : T]  # padded steps do not move
    return MCLBatch(
        scans=pad(batch.scans, (R2, T2, P, 2)),
        mask=pad(batch.mask, (R2, T2, P), False),
        odom=odom,
        step_mask=pad(batch.step_mask, (R2, T2), False),
        window_end=pad(batch.window_end, (R2, K2)),
        window_mask=pad(batch.window_mask, (R2, K2), False),
        dist=pad(batch.dist, (R2, H2, W2), _FAR),
        free=pad(batch.free, (R2, H2, W2), False),
        passable=pad(batch.passable, (R2, H2, W2), False),
        origin=pad(batch.origin, (R2, 2)),
        run_id=pad(batch.run_id, (R2,)),
        res=batch.res,
    )
