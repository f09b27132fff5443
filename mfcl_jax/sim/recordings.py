"""The simulator's runs as ``Recording`` objects: the very scans and odometry ``simulate`` uses.

``simulate`` hands the decision layer submaps; a peer localizer (a particle filter, say) needs
the scans themselves. ``scene_recordings`` derives them exactly as ``simulate`` does (same
PRNG keys, same odometry noise draw, same ray casting), so a peer and our layer are fed
identical data for the same ``(scene, trajectories, seeds, params)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.batch import bucket
from mfcl_jax.sim import SimParams, _odometry_batch, _pad_rows, _run_key
from mfcl_jax.sim.raycast import cast, scan_points
from mfcl_jax.sim.trajectory import sample_path
from mfcl_jax.sources import GroundTruth, Recording, ScanSequence

__all__ = ["scene_recordings"]


def scene_recordings(
    scene, trajectory_names=None, seeds=(0,), params: SimParams | None = None
) -> list[Recording]:
    """One ``Recording`` per (trajectory, seed), trajectory-major, as ``simulate`` derives them.

    The noise draws of ``simulate`` depend on the longest trajectory of the call, so pass the
    same ``trajectory_names`` as the ``simulate`` call to be matched.

    Args:
        scene: a ``Scene`` or a registered scene name.
        trajectory_names: names in ``scene.trajectories`` (default: all, in order).
        seeds: integer seeds.
        params: ``SimParams`` (defaults if None).

    Returns:
        Recordings named ``"<scene>/<trajectory>/seed<seed>"`` holding the floor plan, the scans
        (valid points only, sensor frame), the odometry, and the true poses as ``truth``;
        ``meta`` has ``scene``, ``trajectory``, ``seed``.
    """
    from mfcl_jax.floorplan.scenes import get_scene

    params = SimParams() if params is None else params
    scene = get_scene(scene) if isinstance(scene, str) else scene
    names = list(scene.trajectories) if trajectory_names is None else list(trajectory_names)
    for n in names:
        if n not in scene.trajectories:
            raise KeyError(
                f"scene {scene.name!r} has no trajectory {n!r}; it has {sorted(scene.trajectories)}"
            )
    seeds = [int(s) for s in seeds]
    paths = {n: sample_path(scene.trajectories[n], params.trajectory) for n in names}
    pairs = [(n, s) for n in names for s in seeds]
    t_max = max(len(paths[n].poses) for n in names)
    true_pad = np.stack([_pad_rows(paths[n].poses, t_max) for n, _ in pairs])
    base = [_run_key(s, scene.name, n) for n, s in pairs]
    if params.anchor is None:
        anchors = true_pad[:, 0]
    else:
        anchors = np.broadcast_to(np.asarray(params.anchor, np.float64), (len(pairs), 3))
    # The same draws, shapes and dtypes as ``simulate``: any difference changes the numbers.
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
    counts = [len(paths[n].poses) for n, _ in pairs]
    all_poses = np.concatenate([paths[n].poses for n, _ in pairs])
    all_keys = jnp.concatenate(
        [
            jax.vmap(jax.random.fold_in, in_axes=(None, 0))(jax.random.fold_in(k, 0), jnp.arange(c))
            for k, c in zip(base, counts, strict=True)
        ]
    )
    segs = scene.segments
    seg_pad = np.zeros((bucket(len(segs), minimum=64), 2, 2))
    seg_pad[: len(segs)] = segs
    seg_valid = np.arange(len(seg_pad)) < len(segs)
    ranges = cast(all_poses, seg_pad, params.lidar, key=all_keys, seg_valid=seg_valid)
    pts = np.asarray(scan_points(ranges), dtype=np.float64)
    offsets = np.concatenate([[0], np.cumsum(counts)])

    out = []
    for i, (n, s) in enumerate(pairs):
        c = counts[i]
        scans = [p[np.all(np.isfinite(p), axis=1)] for p in pts[offsets[i] : offsets[i] + c]]
        name = f"{scene.name}/{n}/seed{s}"
        out.append(
            Recording(
                name=name,
                floorplan=scene.floorplan,
                seq=ScanSequence(paths[n].t, scans, odo[i, :c], source=f"<sim {name}>"),
                truth=GroundTruth(paths[n].t, paths[n].poses, source=f"<sim {name}>"),
                meta=dict(scene=scene.name, trajectory=n, seed=s),
            )
        )
    return out
