"""Simulator: a planar LiDAR walked through a built-in scene, cut into sliding-window submaps.

``simulate`` is the one host call: it samples the true scan poses of every trajectory, derives
drifting odometry, ray casts every scan of every (trajectory, seed) pair in ONE jitted call,
and cuts the scans into windows for every ``d_s``. Scans of one (trajectory, seed) are shared by
all ``d_s`` values: ``d_s`` changes only which scans a window holds. Everything is a pure
function of the seeds (JAX keys are derived from the seed and the scene/trajectory names).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from mfcl_jax.batch import RunBatch, SubmapBatch, Truth, bucket
from mfcl_jax.sim.raycast import LidarParams, beam_angles, cast, cast_kernel, scan_points
from mfcl_jax.sim.submaps import SubmapParams, build_submap, window_bounds
from mfcl_jax.sim.trajectory import Path, TrajectoryParams, odometry, sample_path, travelled

__all__ = [
    "SimParams",
    "Simulation",
    "simulate",
    "LidarParams",
    "TrajectoryParams",
    "SubmapParams",
    "Path",
    "cast",
    "cast_kernel",
    "beam_angles",
    "scan_points",
    "sample_path",
    "odometry",
    "window_bounds",
    "build_submap",
    "travelled",
]


@dataclass(frozen=True)
class SimParams:
    """All simulator settings (each part documents its defaults).

    Attributes:
        lidar: the planar LiDAR (Livox Mid-360 ring: 720 beams, 40 m, 2 cm, 2 % dropout).
        trajectory: scan spacing 0.25 m, 0.5 m/s, odometry drift 0.5 % and 0.1 deg/m.
        submap: step 2 m, voxel 0.10 m, 10 m crop radius.
        anchor: the hidden ``^B T_L`` as ``(x, y, theta)``; ``None`` puts L at the true start
            pose of each run (odometry then starts at the identity, as an LIO does).
    """

    lidar: LidarParams = field(default_factory=LidarParams)
    trajectory: TrajectoryParams = field(default_factory=TrajectoryParams)
    submap: SubmapParams = field(default_factory=SubmapParams)
    anchor: tuple[float, float, float] | None = None


class Simulation(NamedTuple):
    """``simulate``'s result; unpacks as ``submaps, runs_batch, truth, runs``."""

    submaps: SubmapBatch
    runs_batch: RunBatch
    truth: Truth
    runs: pd.DataFrame


def _run_key(seed: int, scene: str, traj: str) -> jax.Array:
    # crc32, not hash(): stable across processes.
    tag = zlib.crc32(f"{scene}/{traj}".encode()) & 0x7FFFFFFF
    return jax.random.fold_in(jax.random.PRNGKey(int(seed)), tag)


@jax.jit
def _odometry_batch(true_poses, anchors, noise, drift_xy, drift_yaw):
    return jax.vmap(odometry, in_axes=(0, 0, 0, None, None))(
        true_poses, anchors, noise, drift_xy, drift_yaw
    )


def simulate(
    scene, trajectory_names=None, d_s_values=(6.0,), seeds=(0,), params: SimParams | None = None
) -> Simulation:
    """Simulates runs of a scene: every trajectory x d_s x seed.

    Args:
        scene: a ``Scene`` or a registered scene name.
        trajectory_names: names in ``scene.trajectories`` (default: all, in order).
        d_s_values: window lengths (m).
        seeds: integer seeds; a seed fixes LiDAR noise/dropout and odometry drift.
        params: ``SimParams`` (defaults if None).

    Returns:
        ``Simulation(submaps, runs_batch, truth, runs)``: the padded ``SubmapBatch``, the
        ``RunBatch``, the ``Truth`` (scoring only), and a table with one row per run (columns
        scene, trajectory, d_s, seed, run, n_scans, n_windows, length_m). Runs are ordered
        trajectory-major, then d_s, then seed.
    """
    from mfcl_jax.floorplan.scenes import Scene, get_scene

    params = SimParams() if params is None else params
    scene = get_scene(scene) if isinstance(scene, str) else scene
    if not isinstance(scene, Scene):
        raise TypeError(f"simulate: scene must be a Scene or a name, got {type(scene).__name__}")
    names = list(scene.trajectories) if trajectory_names is None else list(trajectory_names)
    for n in names:
        if n not in scene.trajectories:
            raise KeyError(
                f"scene {scene.name!r} has no trajectory {n!r}; it has {sorted(scene.trajectories)}"
            )
    d_s_values = [float(d) for d in d_s_values]
    seeds = [int(s) for s in seeds]
    if not names or not d_s_values or not seeds:
        raise ValueError(
            f"simulate needs at least one trajectory, d_s and seed; got "
            f"{names=}, {d_s_values=}, {seeds=}"
        )

    # --- true paths (seed independent) and the (trajectory, seed) pairs -------------------
    paths = {n: sample_path(scene.trajectories[n], params.trajectory) for n in names}
    pairs = [(n, s) for n in names for s in seeds]
    t_max = max(len(paths[n].poses) for n in names)
    true_pad = np.stack([_pad_rows(paths[n].poses, t_max) for n, _ in pairs])
    base = [_run_key(s, scene.name, n) for n, s in pairs]
    if params.anchor is None:
        anchors = true_pad[:, 0]
    else:
        anchors = np.broadcast_to(np.asarray(params.anchor, np.float64), (len(pairs), 3))

    # --- odometry: one jitted, vmapped call -------------------------------------------------
    noise = jnp.stack([jax.random.normal(jax.random.fold_in(k, 1), (t_max, 3)) for k in base])
    tp = params.trajectory
    odo = np.asarray(
        _odometry_batch(
            jnp.asarray(true_pad, jnp.float32),
            jnp.asarray(anchors, jnp.float32),
            noise,
            jnp.float32(tp.drift_xy),
            jnp.float32(np.deg2rad(tp.drift_yaw_deg_per_m)),
        ),
        dtype=np.float64,
    )

    # --- ray casting: every scan of every pair in one call ---------------------------------
    counts = [len(paths[n].poses) for n, _ in pairs]
    all_poses = np.concatenate([paths[n].poses for n, _ in pairs])
    all_keys = jnp.concatenate(
        [
            jax.vmap(jax.random.fold_in, in_axes=(None, 0))(jax.random.fold_in(k, 0), jnp.arange(c))
            for k, c in zip(base, counts, strict=True)
        ]
    )
    n_scan = len(all_poses)
    s_cap = bucket(n_scan, minimum=256)
    segs = scene.segments
    m_cap = bucket(len(segs), minimum=64)
    seg_pad = np.zeros((m_cap, 2, 2))
    seg_pad[: len(segs)] = segs
    seg_valid = np.arange(m_cap) < len(segs)
    poses_pad = _pad_rows(all_poses, s_cap)
    keys_pad = (
        jnp.concatenate([all_keys, jnp.zeros((s_cap - n_scan, 2), all_keys.dtype)])
        if s_cap > n_scan
        else all_keys
    )
    ranges = cast(poses_pad, seg_pad, params.lidar, key=keys_pad, seg_valid=seg_valid)
    pts = np.asarray(scan_points(ranges), dtype=np.float64)[:n_scan]
    offsets = np.concatenate([[0], np.cumsum(counts)])

    # --- windows and submaps (host) ----------------------------------------------------------
    rows, subs = [], []
    run_traj, run_true, run_t, run_windows = [], [], [], []
    order = [(n, d, s) for n in names for d in d_s_values for s in seeds]
    for r, (n, d, s) in enumerate(order):
        pi = pairs.index((n, s))
        c = counts[pi]
        X = odo[pi, :c]
        scans = pts[offsets[pi] : offsets[pi] + c]
        wins = window_bounds(travelled(X), d, params.submap.step)
        for w, (j0, j1) in enumerate(wins):
            p, o = build_submap(scans, X, int(j0), int(j1), params.submap)
            subs.append((r, w, int(j1), p, o))
        run_traj.append(X)
        run_true.append(paths[n].poses)
        run_t.append(paths[n].t)
        run_windows.append(wins[:, 1])
        rows.append(
            dict(
                scene=scene.name,
                trajectory=n,
                d_s=d,
                seed=s,
                run=r,
                n_scans=c,
                n_windows=len(wins),
                length_m=float(paths[n].s[-1]),
            )
        )
    runs = pd.DataFrame(
        rows,
        columns=["scene", "trajectory", "d_s", "seed", "run", "n_scans", "n_windows", "length_m"],
    )
    sub_batch, truth_y = _pack_submaps(subs, run_traj, run_true, run_t, params.submap)
    run_batch, truth_traj = _pack_runs(run_traj, run_true, run_t, run_windows, subs)
    truth = Truth(
        traj=truth_traj,
        anchor=np.asarray(anchors, np.float64)[[pairs.index((n, s)) for n, _, s in order]],
        Y=truth_y,
    )
    return Simulation(sub_batch, run_batch, truth, runs)


def _pad_rows(a: np.ndarray, n: int) -> np.ndarray:
    """Pads ``a`` to ``n`` rows by repeating its last row (keeps padded poses finite)."""
    a = np.asarray(a)
    if len(a) >= n:
        return a[:n]
    return np.concatenate([a, np.repeat(a[-1:], n - len(a), axis=0)])


def _pack_submaps(subs, run_traj, run_true, run_t, sp: SubmapParams):
    n = len(subs)
    most = max((len(p) for *_, p, _ in subs), default=0)
    cap = sp.capacity if sp.capacity is not None else bucket(most, minimum=sp.min_capacity)
    points = np.zeros((n, cap, 2), np.float32)
    origins = np.zeros((n, cap, 2), np.float32)
    mask = np.zeros((n, cap), bool)
    X = np.zeros((n, 3), np.float32)
    Y = np.zeros((n, 3), np.float64)
    run = np.zeros(n, np.int32)
    window = np.zeros(n, np.int32)
    t = np.zeros(n, np.float64)
    dropped = np.zeros(n, np.int32)
    for i, (r, w, j1, p, o) in enumerate(subs):
        k = min(len(p), cap)
        points[i, :k], origins[i, :k], mask[i, :k] = p[:k], o[:k], True
        dropped[i] = len(p) - k
        X[i], Y[i] = run_traj[r][j1], run_true[r][j1]
        run[i], window[i], t[i] = r, w, run_t[r][j1]
    batch = SubmapBatch(
        points=jnp.asarray(points),
        origins=jnp.asarray(origins),
        mask=jnp.asarray(mask),
        X=jnp.asarray(X),
        run=jnp.asarray(run),
        window=jnp.asarray(window),
        t=t,
        n_dropped=jnp.asarray(dropped),
    )
    return batch, Y


def _pack_runs(run_traj, run_true, run_t, run_windows, subs):
    R = len(run_traj)
    T = max(len(x) for x in run_traj)
    K = max(1, max(len(w) for w in run_windows))
    traj = np.stack([_pad_rows(x, T) for x in run_traj]).astype(np.float32)
    true = np.stack([_pad_rows(x, T) for x in run_true]).astype(np.float64)
    traj_t = np.stack([_pad_rows(x[:, None], T)[:, 0] for x in run_t]).astype(np.float64)
    traj_mask = np.arange(T)[None, :] < np.array([len(x) for x in run_traj])[:, None]
    window_end = np.zeros((R, K), np.int32)
    window_mask = np.zeros((R, K), bool)
    submap = np.full((R, K), -1, np.int32)
    for r, w in enumerate(run_windows):
        window_end[r, : len(w)] = w
        window_mask[r, : len(w)] = True
    for i, (r, w, *_rest) in enumerate(subs):
        submap[r, w] = i
    batch = RunBatch(
        traj=jnp.asarray(traj),
        traj_t=traj_t,
        traj_mask=jnp.asarray(traj_mask),
        window_end=jnp.asarray(window_end),
        window_mask=jnp.asarray(window_mask),
        submap=jnp.asarray(submap),
    )
    return batch, true
