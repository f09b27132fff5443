"""A walk with a 3-D LiDAR, and the 2-D ring at the same poses.

The walk, its odometry and the 2-D ring come from ``sources.simulated.simulate`` (same seed and
tag: same true poses, same odometry and, without clutter, the same 2-D scans as
``simulate_walk``); the 3-D cloud is cast at the same poses with keys derived from the same run
key, so a 3-D walk and its 2-D twin differ only in the sensor.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.sim.lidar3d import Lidar3DParams, cast3d
from mfcl_jax.sim.raycast import LidarParams
from mfcl_jax.sim.trajectory import TrajectoryParams
from mfcl_jax.sim.world3d import build_geometry

__all__ = ["Walk3D", "walk3d", "scene_walk3d"]


class Walk3D(NamedTuple):
    """One simulated walk.

    Attributes:
        t: ``(T,)`` scan times (s).
        true: ``(T, 3)`` true base poses in B (scoring only).
        odom: ``(T, 3)`` drifting odometry in L (L = the true start pose).
        clouds: ``(T, B, 3)`` float32 3-D scans in the sensor frame, NaN rows for no return.
        scans2d: ``T`` arrays ``(n_i, 2)``: the planar LiDAR at the same poses, against the wall
            faces and the clutter taller than the 3-D sensor's height (what a horizontal ring
            at that height sees).
    """

    t: np.ndarray
    true: np.ndarray
    odom: np.ndarray
    clouds: np.ndarray
    scans2d: list


def walk3d(
    floorplan,
    waypoints,
    sensor: Lidar3DParams | None = None,
    *,
    clutter=None,
    clutter_height=None,
    h_ceil: float = 2.8,
    seed: int = 0,
    trajectory: TrajectoryParams | None = None,
    lidar2d: LidarParams | None = None,
    tag: str = "user",
) -> Walk3D:
    """Simulates a walk along ``waypoints`` with a 3-D LiDAR (and its 2-D twin).

    Args:
        floorplan: a ``Floorplan`` (its wall faces are extruded to ``h_ceil``).
        waypoints: ``(P, 2)`` polyline in B.
        sensor: the 3-D LiDAR (default ``Lidar3DParams()``: Livox Mid-360-like at 0.5 m).
        clutter, clutter_height: ``(K, 2, 2)`` segments and ``(K,)`` heights (``Scene``'s).
        h_ceil: ceiling height (m).
        seed: noise, dropout, pattern and odometry drift seed.
        trajectory: scan spacing, speed and drift (default ``TrajectoryParams()``).
        lidar2d: the 2-D twin's LiDAR (default ``LidarParams()``).
        tag: names the walk in the key derivation (as ``simulate_walk``'s ``tag``).
    """
    from mfcl_jax.sim import SimParams
    from mfcl_jax.sim.scenes import Scene
    from mfcl_jax.sources.simulated import run_key, simulate

    sensor = sensor or Lidar3DParams()
    walls = np.asarray(floorplan.wall_faces, np.float64)
    segs = walls
    if clutter is not None and len(clutter):
        c = np.asarray(clutter, np.float64).reshape(-1, 2, 2)
        h = np.full(len(c), np.inf) if clutter_height is None else np.asarray(clutter_height)
        segs = np.concatenate([walls, c[h > sensor.height]])
    name = floorplan.name or "plan"
    scene = Scene(name, floorplan, np.zeros((0, 2, 2)), {tag: waypoints})
    params = SimParams(lidar=lidar2d or LidarParams(), trajectory=trajectory or TrajectoryParams())
    rec = simulate(scene, [tag], [seed], params, segments=segs)[0]
    true = rec.truth.poses
    idx = jnp.arange(len(true))
    k3 = jax.random.fold_in(run_key(seed, name, tag), 2)
    keys3d = jax.vmap(jax.random.fold_in, in_axes=(None, 0))(k3, idx)
    geom = build_geometry(walls, clutter, clutter_height, h_ceil)
    # Pad the scan count to a multiple of 64: one compilation for walks of similar length.
    n = len(true)
    cap = -(-n // 64) * 64
    poses = np.concatenate([true, np.repeat(true[-1:], cap - n, 0)])
    keys = jnp.concatenate([keys3d, jnp.zeros((cap - n, 2), keys3d.dtype)])
    clouds = np.asarray(cast3d(poses, geom, sensor, key=keys))[:n]
    return Walk3D(rec.seq.times, true, rec.seq.odometry, clouds, list(rec.seq.scans))


def scene_walk3d(scene, name: str, sensor: Lidar3DParams | None = None, **kwargs) -> Walk3D:
    """``walk3d`` along the trajectory ``name`` of a built-in ``Scene``, with its clutter and
    clutter heights (``kwargs`` go to ``walk3d``)."""
    if name not in scene.trajectories:
        raise KeyError(
            f"scene {scene.name!r} has no trajectory {name!r}; it has {sorted(scene.trajectories)}"
        )
    kwargs.setdefault("tag", f"{scene.name}/{name}")
    return walk3d(
        scene.floorplan,
        scene.trajectories[name],
        sensor,
        clutter=scene.clutter,
        clutter_height=scene.clutter_height,
        **kwargs,
    )
