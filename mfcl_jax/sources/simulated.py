"""Simulated recordings: a planar LiDAR walked through a scene (built-in, procedural or a
loaded floor plan with waypoints).

``simulate`` samples the true scan poses of every (trajectory, seed) pair, derives drifting
odometry for all of them in one jitted call, and ray casts every scan of every pair in ONE
jitted call. The result is one ``Recording`` per pair, cut into windows later like any other
input (``mfcl_jax.windows``). Everything is a pure function of the seeds: JAX keys are derived
from the seed and the scene / trajectory names (crc32, stable across processes).

An odometry restart (``SimParams.restart_at``) re-zeroes the odometry at that fraction of the
path, as an LIO that is restarted does: the odometry frame after it is unrelated to the one
before it. Odometry latency (``SimParams.odom_latency``) gives each scan the odometry pose of
that many seconds before it.
"""

from __future__ import annotations

import zlib
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.io.errors import DataError
from mfcl_jax.sim import SimParams
from mfcl_jax.sim.raycast import cast, scan_points
from mfcl_jax.sim.trajectory import odometry, sample_path
from mfcl_jax.sources.recording import GroundTruth, Recording
from mfcl_jax.sources.sequence import ScanSequence

__all__ = ["simulate", "simulate_walk", "simulate_dataset", "run_key"]

CHUNK = 512  # scans per ray-casting call
# Surfaces are padded to a multiple of this (masked): a cast costs beams x surfaces, so the
# padding is paid on every beam (powers of two wasted 35 % of the benchmark's casts)
SEG_STEP = 128


def run_key(seed: int, scene: str, traj: str) -> jax.Array:
    """The PRNG key of one (scene, trajectory, seed) run."""
    tag = zlib.crc32(f"{scene}/{traj}".encode()) & 0x7FFFFFFF
    return jax.random.fold_in(jax.random.PRNGKey(int(seed)), tag)


def _steps(n: int) -> int:
    """Steps padded to a multiple of 256: every run length shares a few compilations."""
    return max(256, -(-int(n) // 256) * 256)


@partial(jax.jit, static_argnames="n")
def _scan_keys(keys, n):
    """``(P, n, 2)``: key of scan ``i`` of run ``p`` = ``fold_in(fold_in(keys[p], 0), i)``."""
    sub = jax.vmap(lambda k: jax.random.fold_in(k, 0))(keys)
    return jax.vmap(lambda k: jax.vmap(lambda i: jax.random.fold_in(k, i))(jnp.arange(n)))(sub)


@jax.jit
def _odometry_batch(true_poses, anchors, noise, drift_xy, drift_yaw):
    return jax.vmap(odometry, in_axes=(0, 0, 0, None, None))(
        true_poses, anchors, noise, drift_xy, drift_yaw
    )


def _pad_rows(a: np.ndarray, n: int) -> np.ndarray:
    a = np.asarray(a)
    if len(a) >= n:
        return a[:n]
    return np.concatenate([a, np.repeat(a[-1:], n - len(a), axis=0)])


def _restart(odo: np.ndarray, at: float | None) -> np.ndarray:
    """Odometry re-zeroed at fraction ``at`` of the samples (``None``: unchanged)."""
    if at is None:
        return odo
    r = int(round(at * (len(odo) - 1)))
    if r <= 0:
        return odo
    out = odo.copy()
    out[r:] = np.asarray(se2.between(odo[r], odo[r:]), np.float64)
    return out


def _late(odo: np.ndarray, t: np.ndarray, latency: float) -> np.ndarray:
    """The odometry lagging by ``latency`` s: poses interpolated at ``t - latency`` (the first
    pose before the start; yaw unwrapped, interpolated and wrapped again)."""
    if latency <= 0:
        return odo
    q = np.maximum(t - latency, t[0])
    yaw = np.unwrap(odo[:, 2])
    out = np.stack([np.interp(q, t, odo[:, 0]), np.interp(q, t, odo[:, 1]),
                    np.interp(q, t, yaw)], axis=1)  # fmt: skip
    out[:, 2] = se2.wrap_host(out[:, 2])
    return out


def simulate(
    scene, trajectory_names=None, seeds=(0,), params: SimParams | None = None, segments=None
) -> list[Recording]:
    """One ``Recording`` per (trajectory, seed) of a scene (trajectory-major order).

    Args:
        scene: a ``Scene`` or a registered scene name.
        trajectory_names: names in ``scene.trajectories`` (default: all, in order).
        seeds: integer seeds; a seed fixes LiDAR noise / dropout and odometry drift.
        params: ``SimParams`` (defaults if None).
        segments: surfaces the LiDAR sees (default ``scene.segments``: as built + clutter).

    Returns:
        Recordings named ``"{scene}/{trajectory}/s{seed}"`` with ground truth; ``meta`` holds
        ``scene``, ``trajectory``, ``seed``, ``length_m``.
    """
    from mfcl_jax.sim.scenes import Scene, get_scene

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
    seeds = [int(s) for s in seeds]
    if not names or not seeds:
        raise ValueError(f"simulate needs a trajectory and a seed; got {names=}, {seeds=}")
    segs = np.asarray(scene.segments if segments is None else segments, np.float64)
    if len(segs) == 0:
        raise DataError(f"{scene.name}: no surfaces to simulate a LiDAR against")

    paths = {n: sample_path(scene.trajectories[n], params.trajectory) for n in names}
    pairs = [(n, s) for n in names for s in seeds]
    t_max = max(len(paths[n].poses) for n in names)
    true_pad = np.stack([_pad_rows(paths[n].poses, t_max) for n, _ in pairs])
    keys = [run_key(s, scene.name, n) for n, s in pairs]
    if params.anchor is None:
        anchors = true_pad[:, 0]
    else:
        anchors = np.broadcast_to(np.asarray(params.anchor, np.float64), (len(pairs), 3))
    noise = jnp.stack([jax.random.normal(jax.random.fold_in(k, 1), (t_max, 3)) for k in keys])
    tp = params.trajectory
    # Padded to a step bucket (repeated last pose, zero noise: a causal chain, so the real
    # steps are unchanged) for a shared compilation; cut back after.
    t_b = _steps(t_max)
    odo = np.asarray(
        _odometry_batch(
            jnp.asarray(np.stack([_pad_rows(t, t_b) for t in true_pad]), jnp.float32),
            jnp.asarray(anchors, jnp.float32),
            jnp.pad(noise, ((0, 0), (0, t_b - t_max), (0, 0))),
            jnp.float32(tp.drift_xy),
            jnp.float32(np.deg2rad(tp.drift_yaw_deg_per_m)),
        ),
        np.float64,
    )[:, :t_max]

    counts = [len(paths[n].poses) for n, _ in pairs]
    all_poses = np.concatenate([paths[n].poses for n, _ in pairs])
    per_run = _scan_keys(jnp.stack(keys), _steps(max(counts)))
    all_keys = jnp.concatenate([per_run[i, :c] for i, c in enumerate(counts)])
    n_scan = len(all_poses)
    # Fixed shapes: scans in chunks of CHUNK, surfaces in buckets of SEG_STEP, so every
    # building and run length shares a handful of compilations.
    m_cap = -(-len(segs) // SEG_STEP) * SEG_STEP
    seg_pad = np.zeros((m_cap, 2, 2))
    seg_pad[: len(segs)] = segs
    seg_valid = np.arange(m_cap) < len(segs)
    s_cap = -(-n_scan // CHUNK) * CHUNK
    keys_pad = jnp.concatenate([all_keys, jnp.zeros((s_cap - n_scan, 2), all_keys.dtype)])
    poses_pad = _pad_rows(all_poses, s_cap)
    ranges = np.concatenate(
        [
            np.asarray(
                cast(
                    poses_pad[a : a + CHUNK],
                    seg_pad,
                    params.lidar,
                    keys_pad[a : a + CHUNK],
                    seg_valid,
                )
            )  # fmt: skip
            for a in range(0, s_cap, CHUNK)
        ]
    )
    pts = np.asarray(scan_points(ranges), np.float64)[:n_scan]
    offsets = np.concatenate([[0], np.cumsum(counts)])

    out = []
    for i, (n, s) in enumerate(pairs):
        c = counts[i]
        scans = [p[np.all(np.isfinite(p), 1)] for p in pts[offsets[i] : offsets[i] + c]]
        name = f"{scene.name}/{n}/s{s}"
        path = paths[n]
        late = _late(odo[i, :c], np.asarray(path.t, np.float64), params.odom_latency)
        seq = ScanSequence(path.t, scans, _restart(late, params.restart_at), name)
        meta = dict(scene=scene.name, trajectory=n, seed=s, length_m=float(path.s[-1]))
        out.append(Recording(name, scene.floorplan, seq, GroundTruth(path.t, path.poses), meta))
    return out


def simulate_walk(floorplan, waypoints, seed: int = 0, params: SimParams | None = None, tag="walk"):
    """A ``Recording`` of a LiDAR walk along ``waypoints`` through a loaded floor plan (the
    LiDAR sees the plan's wall faces only)."""
    from mfcl_jax.sim.scenes import Scene

    scene = Scene(floorplan.name or "plan", floorplan, np.zeros((0, 2, 2)), {tag: waypoints})
    return simulate(scene, [tag], [seed], params)[0]


def simulate_dataset(
    floorplan,
    waypoints,
    out,
    seed: int = 0,
    params: SimParams | None = None,
    overwrite: bool = False,
    where: str = "<waypoints>",
    odom_rate: float | None = None,
):
    """Writes a dataset folder (atomically) of a walk along ``waypoints`` in ``floorplan``.

    ``waypoints`` are in the plan's file frame (``Floorplan.offset`` applies) and the ground
    truth is written in that frame too.

    The LiDAR sees the plan's wall faces only (no clutter is known for a user's building);
    the folder holds the floor plan as GeoJSON, ``odometry.tum``, ``scans/<t>.pcd`` and
    ``groundtruth.tum``. With ``odom_rate`` (Hz) the odometry is written at that rate with its
    own stamps, as wheel odometry or an LIO publishes it (interpolated along the simulated
    odometry, from the first scan's time to the last's), instead of one pose per scan.
    """
    from mfcl_jax.floorplan.origin import to_local_frame, to_plan_frame
    from mfcl_jax.sources.dataset_write import write_dataset
    from mfcl_jax.sources.walks import check_waypoints

    wp = to_local_frame(np.asarray(waypoints, np.float64), floorplan.offset)
    check_waypoints(floorplan, wp, where)
    rec = simulate_walk(floorplan, wp, seed, params)
    gt = to_plan_frame(rec.truth.poses, floorplan.offset)
    odo, o_times = rec.seq.odometry, None
    if odom_rate is not None:
        from mfcl_jax.io.timesync import interpolate_se2

        if not odom_rate > 0:
            raise ValueError(f"odom_rate must be positive, got {odom_rate!r}")
        t = np.asarray(rec.seq.times, np.float64)
        o_times = np.arange(t[0], t[-1], 1.0 / odom_rate)
        o_times = np.append(o_times[o_times < t[-1] - 1e-6], t[-1])
        odo = interpolate_se2(t, np.asarray(odo, np.float64), o_times)
    return write_dataset(
        out, floorplan, rec.seq.times, rec.seq.scans, odo, groundtruth=gt,
        overwrite=overwrite, odom_times=o_times,
    )  # fmt: skip
