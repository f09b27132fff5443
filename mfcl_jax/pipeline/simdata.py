"""A dataset folder from any floor plan and a waypoint list, with the simulator.

The robot walks the waypoint polyline (``sim.sample_path``: a scan every 0.25 m, rounded
corners), its ray-cast LiDAR sees the floor plan's wall faces (no clutter: none is known for
a user's building), and its odometry drifts as ``sim.odometry`` models it, starting at the
identity (L is the true start pose). The dataset holds the floor plan as GeoJSON (exactly the
model that was simulated), ``odometry.tum``, ``scans/<t>.pcd`` and ``groundtruth.tum``.
"""

from __future__ import annotations

import csv
import math
import zlib
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from shapely.geometry import LineString

from mfcl_jax.io.dataset import write_dataset
from mfcl_jax.io.errors import DataError
from mfcl_jax.sim import SimParams
from mfcl_jax.sim.raycast import cast, scan_points
from mfcl_jax.sim.trajectory import odometry, sample_path

__all__ = ["read_waypoints", "check_waypoints", "simulate_scans", "simulate_dataset"]


def read_waypoints(path) -> np.ndarray:
    """Reads ``x,y`` per line (a header line is optional; blank and ``#`` lines skipped).

    Raises:
        DataError: naming the line and field of the first bad value.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise DataError(f"{path}: cannot read ({e})") from None
    pts, header_seen = [], False
    for no, row in enumerate(csv.reader(text.splitlines()), 1):
        cells = [c.strip() for c in row]
        if not cells or not any(cells) or cells[0].startswith("#"):
            continue
        if not pts and not header_seen and [c.lower() for c in cells] == ["x", "y"]:
            header_seen = True
            continue
        if len(cells) != 2:
            raise DataError(f"{path}: line {no}: expected 2 fields x,y, got {len(cells)}")
        vals = []
        for name, c in zip("xy", cells, strict=True):
            try:
                v = float(c)
            except ValueError:
                raise DataError(f"{path}: line {no}: field {name}: not a number {c!r}") from None
            if not math.isfinite(v):
                raise DataError(f"{path}: line {no}: field {name}: non-finite value {c!r}")
            vals.append(v)
        if pts and np.hypot(vals[0] - pts[-1][0], vals[1] - pts[-1][1]) < 1e-9:
            raise DataError(f"{path}: line {no}: waypoint repeats the previous one")
        pts.append(vals)
    if len(pts) < 2:
        raise DataError(f"{path}: need at least 2 waypoints, got {len(pts)}")
    return np.asarray(pts, np.float64)


def check_waypoints(fp, wp, where: str = "<waypoints>") -> None:
    """Raises ``DataError`` when a waypoint lies in a wall or a leg crosses one."""
    solid = fp.wall_solid
    for i in range(len(wp) - 1):
        leg = LineString(wp[i : i + 2])
        if leg.intersects(solid):
            hit = leg.intersection(solid)
            p = np.asarray(hit.representative_point().coords[0])
            raise DataError(
                f"{where}: waypoint {i + 1} -> {i + 2} ({wp[i][0]:.2f}, {wp[i][1]:.2f}) -> "
                f"({wp[i + 1][0]:.2f}, {wp[i + 1][1]:.2f}) passes through a wall of "
                f"{fp.name} near ({p[0]:.2f}, {p[1]:.2f})"
            )


def simulate_scans(
    fp, waypoints, seed: int = 0, params: SimParams | None = None, tag: str = "user"
):
    """True poses, drifting odometry and sensor-frame scans along ``waypoints``.

    Returns:
        ``(t (T,), truth (T, 3), odom (T, 3), scans list of (n_i, 2))``.
    """
    params = params or SimParams()
    path = sample_path(waypoints, params.trajectory)
    true = path.poses
    key = jax.random.fold_in(jax.random.PRNGKey(int(seed)), zlib.crc32(tag.encode()) & 0x7FFFFFFF)
    noise = jax.random.normal(jax.random.fold_in(key, 1), true.shape)
    tp = params.trajectory
    odo = np.asarray(
        odometry(
            jnp.asarray(true, jnp.float32),
            jnp.asarray(true[0], jnp.float32),
            noise,
            tp.drift_xy,
            np.deg2rad(tp.drift_yaw_deg_per_m),
        ),
        np.float64,
    )
    keys = jax.vmap(jax.random.fold_in, in_axes=(None, 0))(
        jax.random.fold_in(key, 0), jnp.arange(len(true))
    )
    segs = fp.wall_faces
    if len(segs) == 0:
        raise DataError(f"{fp.source}: floor plan has no wall faces to simulate a LiDAR against")
    ranges = cast(true, segs, params.lidar, key=keys)
    pts = np.asarray(scan_points(ranges), np.float64)
    scans = [p[np.all(np.isfinite(p), 1)] for p in pts]
    return path.t, true, odo, scans


def simulate_dataset(
    floorplan,
    waypoints,
    out,
    seed: int = 0,
    params: SimParams | None = None,
    overwrite: bool = False,
    where: str = "<waypoints>",
) -> Path:
    """Writes a dataset folder (atomically) simulated along ``waypoints`` in ``floorplan``.

    Args:
        floorplan: a ``Floorplan`` (possibly moved to a local origin, ``Floorplan.offset``).
        waypoints: ``(P, 2)`` polyline in B, in the plan's file frame; the ground truth is
            written in that frame too.
        out: the dataset folder to create.
        seed: LiDAR noise/dropout and odometry drift seed.
        params: ``SimParams``.
        overwrite: replace an existing folder.
        where: name of the waypoint source, for messages.
    """
    from mfcl_jax.floorplan.origin import to_local_frame, to_plan_frame

    wp = to_local_frame(waypoints, floorplan.offset)
    check_waypoints(floorplan, wp, where)
    t, true, odo, scans = simulate_scans(floorplan, wp, seed, params)
    gt = to_plan_frame(true, floorplan.offset)
    return write_dataset(out, floorplan, t, scans, odo, groundtruth=gt, overwrite=overwrite)
