"""Multi-ring 3-D LiDAR: ray casting against an extruded floor plan, a floor, a ceiling, boxes.

The world is a ``world3d.Geometry3D`` (walls extruded from the plan, floor, ceiling, boxes).

The sensor (``Lidar3DParams``): rings of fixed elevation, ``n_azimuth`` beams each, at
``height`` above the floor, optionally tilted on its mount (roll, then pitch). Presets:

* ``livox_mid360``: 360 x 59 deg (elevation -7..52 deg), 40 m at 10 % reflectivity, 0.1 m
  minimum range, 2 cm precision. The real sensor scans a non-repetitive rosette, about 20 000
  points per 10 Hz frame. We emulate a frame by 40 rings (1.475 deg apart, cell centres of the
  59 deg field) x 512 azimuths = 20 480 beams, and the non-repetitive coverage by shifting every
  ring of a scan by one random elevation offset (within half a ring spacing) and every azimuth
  by a random fraction of a step: over a few scans the rings fill the field as the rosette does.
* ``velodyne_vlp16``: 16 rings at 2 deg over -15..+15 deg, 900 azimuths (0.4 deg), 100 m.
* ``ouster_os1``: 32 or 64 rings evenly over -22.5..+22.5 deg, 512 azimuths, 100 m.

A beam that hits nothing (within ``max_range``), hits closer than ``min_range`` or drops out
returns NaN, as in the 2-D caster (``raycast``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.sim.world3d import Geometry3D, first_hit, nearest_faces

__all__ = [
    "Lidar3DParams",
    "livox_mid360",
    "velodyne_vlp16",
    "ouster_os1",
    "beam_directions",
    "cast3d",
    "cast3d_kernel",
]


@dataclass(frozen=True)
class Lidar3DParams:
    """A multi-ring LiDAR and its mount (defaults: ``livox_mid360()``'s values).

    Attributes:
        elevation_deg: ring elevations (deg, up positive); their number is static.
        n_azimuth: beams per ring over 360 deg (static).
        height: sensor origin above the floor (m): 0.5 for a small robot, 1.2 handheld.
        roll_deg, pitch_deg: mount tilt (sensor frame = base frame rotated by roll about x,
            then pitch about y; ``cloud3d.Mount(rpy=(roll, pitch, 0))`` undoes it).
        min_range, max_range: valid range interval (m).
        sigma: Gaussian range noise (m).
        dropout: probability that a beam returns nothing.
        nonrepetitive: shift the pattern by a random offset per scan (see the module docstring).
    """

    elevation_deg: tuple = tuple(-7.0 + (i + 0.5) * 59.0 / 40 for i in range(40))
    n_azimuth: int = 512
    height: float = 0.5
    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    min_range: float = 0.1
    max_range: float = 40.0
    sigma: float = 0.02
    dropout: float = 0.02
    nonrepetitive: bool = True

    def __post_init__(self):
        el = np.asarray(self.elevation_deg, float)
        object.__setattr__(self, "elevation_deg", tuple(float(e) for e in el.reshape(-1)))
        if el.size == 0 or not np.all(np.abs(el) < 90):
            raise ValueError(f"Lidar3DParams.elevation_deg: need rings in (-90, 90), got {el}")
        if not (isinstance(self.n_azimuth, int | np.integer) and self.n_azimuth > 0):
            raise ValueError(f"Lidar3DParams.n_azimuth must be a positive int: {self.n_azimuth!r}")
        if not 0 <= self.min_range < self.max_range:
            raise ValueError(
                f"Lidar3DParams needs 0 <= min_range < max_range, got "
                f"min_range={self.min_range!r}, max_range={self.max_range!r}"
            )
        if not (self.sigma >= 0 and 0 <= self.dropout < 1 and self.height > 0):
            raise ValueError(
                f"Lidar3DParams needs sigma >= 0, 0 <= dropout < 1, height > 0; got "
                f"sigma={self.sigma!r}, dropout={self.dropout!r}, height={self.height!r}"
            )

    @property
    def n_beams(self) -> int:
        return len(self.elevation_deg) * int(self.n_azimuth)

    @property
    def ring_spacing_deg(self) -> float:
        el = self.elevation_deg
        return (max(el) - min(el)) / (len(el) - 1) if len(el) > 1 else 0.0


def livox_mid360(**overrides) -> Lidar3DParams:
    """Livox Mid-360-like: 40 rings over -7..52 deg x 512 azimuths, non-repetitive."""
    return replace(Lidar3DParams(), **overrides)


def velodyne_vlp16(**overrides) -> Lidar3DParams:
    """Velodyne VLP-16-like: 16 rings over -15..+15 deg x 900 azimuths, 100 m, 3 cm."""
    base = Lidar3DParams(
        elevation_deg=tuple(np.linspace(-15.0, 15.0, 16)),
        n_azimuth=900,
        min_range=0.4,
        max_range=100.0,
        sigma=0.03,
        nonrepetitive=False,
    )
    return replace(base, **overrides)


def ouster_os1(channels: int = 64, **overrides) -> Lidar3DParams:
    """Ouster OS1-like: ``channels`` rings evenly over -22.5..+22.5 deg x 512 azimuths."""
    base = Lidar3DParams(
        elevation_deg=tuple(np.linspace(-22.5, 22.5, int(channels))),
        n_azimuth=512,
        min_range=0.3,
        max_range=100.0,
        sigma=0.03,
        nonrepetitive=False,
    )
    return replace(base, **overrides)


def beam_directions(elevation, n_azimuth: int, el_shift=0.0, az_shift=0.0) -> jax.Array:
    """Unit beam directions in the sensor frame ``(R * n_azimuth, 3)``, ring-major.

    Args:
        elevation: ``(R,)`` ring elevations (rad).
        n_azimuth: beams per ring (static).
        el_shift: added to every elevation (rad).
        az_shift: azimuth offset in steps (``0 <= az_shift < 1``); beam ``a`` points at
            ``2 pi (a + az_shift) / n_azimuth``.
    """
    el = jnp.asarray(elevation, jnp.float32) + el_shift
    az = (jnp.arange(n_azimuth, dtype=jnp.float32) + az_shift) * (2 * jnp.pi / n_azimuth)
    ce = jnp.cos(el)[:, None]
    d = jnp.stack(
        [
            ce * jnp.cos(az)[None],
            ce * jnp.sin(az)[None],
            jnp.broadcast_to(jnp.sin(el)[:, None], (el.shape[0], n_azimuth)),
        ],
        axis=-1,
    )
    return d.reshape(-1, 3)


def _rotation(roll, pitch, yaw):
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (3, 3)."""
    cr, sr, cp, sp = jnp.cos(roll), jnp.sin(roll), jnp.cos(pitch), jnp.sin(pitch)
    cy, sy = jnp.cos(yaw), jnp.sin(yaw)
    rx = jnp.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]], jnp.float32)
    ry = jnp.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]], jnp.float32)
    rz = jnp.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]], jnp.float32)
    return rz @ ry @ rx


def cast3d_kernel(
    poses,
    keys,
    g: Geometry3D,
    elevation,
    n_azimuth,
    height,
    roll,
    pitch,
    min_range,
    max_range,
    sigma,
    dropout,
    jitter,
    max_faces=1024,
    chunk=8,
):
    """3-D scans at many poses (pure; ``n_azimuth``, ``max_faces``, ``chunk`` static).

    Args:
        poses: ``(S, 3)`` planar base poses ``(x, y, yaw)`` in the geometry's frame.
        keys: ``(S, 2)`` PRNG keys, one per scan (pattern shift, noise, dropout).
        g: the ``Geometry3D``.
        elevation: ``(R,)`` ring elevations (rad).
        height, roll, pitch: sensor height (m) and mount tilt (rad).
        min_range, max_range, sigma, dropout: as ``Lidar3DParams``.
        jitter: 1.0 for the non-repetitive per-scan shift, 0.0 for a fixed pattern.
        max_faces: each scan is cast against its ``max_faces`` nearest vertical faces only
            (cost grows with beams x faces); a return farther (horizontally) than the nearest
            face left out could be wrong, so it is dropped: exact up to that distance.
        chunk: rings per vectorised step (bounds memory at chunk * n_azimuth * faces).

    Returns:
        ``(S, R * n_azimuth, 3)`` float32 points in the sensor frame, NaN where no return.
    """
    n_ring = elevation.shape[0]
    spacing = (jnp.max(elevation) - jnp.min(elevation)) / jnp.maximum(n_ring - 1, 1)

    def one(args):
        pose, key = args
        u = jax.random.uniform(jax.random.fold_in(key, 0), (2,))
        dirs = beam_directions(
            elevation, n_azimuth, jitter * (u[0] - 0.5) * spacing, jitter * u[1]
        )  # (B, 3) sensor frame
        world = dirs @ _rotation(roll, pitch, pose[2]).T
        origin = jnp.stack([pose[0], pose[1], height])
        gs, reach = nearest_faces(g, pose[:2], max_faces)
        # One ring per map item (its beams vectorised), ``chunk`` rings at a time.
        r = jax.lax.map(
            lambda d: first_hit(origin, d, gs),
            world.reshape(n_ring, n_azimuth, 3),
            batch_size=chunk,
        ).reshape(-1)
        r = jnp.where(r * jnp.linalg.norm(world[:, :2], axis=-1) > reach, jnp.inf, r)
        noisy = r + sigma * jax.random.normal(jax.random.fold_in(key, 1), r.shape, r.dtype)
        kept = jax.random.uniform(jax.random.fold_in(key, 2), r.shape) >= dropout
        ok = jnp.isfinite(r) & (r <= max_range) & (noisy >= min_range) & kept
        return jnp.where(ok, noisy, jnp.nan)[:, None] * dirs

    return jax.lax.map(one, (poses, keys))


_cast3d_jit = jax.jit(cast3d_kernel, static_argnames=("n_azimuth", "max_faces", "chunk"))


def cast3d(
    poses,
    geometry: Geometry3D,
    params: Lidar3DParams = Lidar3DParams(),
    key=None,
    max_faces: int = 1024,
):
    """Simulated 3-D scans at many poses (one jitted call; compiled once per shape).

    Args:
        poses: ``(S, 3)`` planar poses ``(x, y, yaw)`` of the sensor's base in the floor plan.
        geometry: ``build_geometry(...)``.
        params: the sensor.
        key: one PRNG key (split per scan) or ``(S, 2)`` keys, one per scan.
        max_faces: faces per scan (see ``cast3d_kernel``); the default keeps every face of
            buildings up to 1024 faces; large IFC storeys trade far returns for speed.

    Returns:
        ``(S, B, 3)`` float32 points in the sensor frame (``B = params.n_beams``, ring-major:
        beam ``r * n_azimuth + a``), NaN rows for no return.
    """
    poses = jnp.asarray(poses, jnp.float32).reshape(-1, 3)
    if not bool(jnp.all(jnp.isfinite(poses))):
        raise ValueError("cast3d: poses contain NaN or inf")
    if not params.height < float(geometry.h_ceil):
        raise ValueError(
            f"cast3d: sensor height {params.height} m must be below the ceiling "
            f"{float(geometry.h_ceil)} m"
        )
    key = jax.random.PRNGKey(0) if key is None else jnp.asarray(key)
    keys = key if key.ndim == 2 else jax.random.split(key, poses.shape[0])
    if keys.shape[0] != poses.shape[0]:
        raise ValueError(f"cast3d: {keys.shape[0]} keys for {poses.shape[0]} poses")
    f32 = jnp.float32
    return _cast3d_jit(
        poses,
        keys,
        geometry,
        jnp.deg2rad(jnp.asarray(params.elevation_deg, f32)),
        n_azimuth=int(params.n_azimuth),
        height=f32(params.height),
        roll=f32(np.deg2rad(params.roll_deg)),
        pitch=f32(np.deg2rad(params.pitch_deg)),
        min_range=f32(params.min_range),
        max_range=f32(params.max_range),
        sigma=f32(params.sigma),
        dropout=f32(params.dropout),
        jitter=f32(1.0 if params.nonrepetitive else 0.0),
        max_faces=int(max_faces),
    )
