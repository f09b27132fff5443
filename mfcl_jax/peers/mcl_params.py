"""Settings of the Monte Carlo localization peer (``mcl``): which are static, which traced.

``MCLParams`` checks every value on construction and splits them into the jitted filter's
static keyword arguments and its traced float32 arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

__all__ = ["MCLParams"]


@dataclass(frozen=True)
class MCLParams:
    """Particle filter settings.

    Static (a change recompiles): ``n_particles``, ``n_beams``, ``chunk``, and whether
    recovery is on. All others are traced.

    Attributes:
        n_particles: particles per (run, seed). A global filter needs them to cover the free
            space: 8192 is 19 per m^2 in ``three_rooms`` (426 m^2 at >= 0.2 m from walls) and
            52 in ``symmetric_bays`` (157 m^2); over both scenes the final pose is right in
            83 % of (run, seed) pairs (4096: 67 %, 16384: 89 %; ``benchmarks/mcl.py``).
            AMCL caps at 5000 by default (KLD sampling shrinks the cloud below that).
        n_beams: scan points used per update, picked evenly among the valid points (AMCL's
            ``max_beams``: 30 in ROS 1, 60 in nav2).
        alpha: odometry noise alpha1..alpha4 (AMCL defaults 0.2 each, sized for wheel
            odometry; ours is a LIO keyframe chain, hence smaller).
        sigma_hit, z_hit, z_rand: likelihood-field model (AMCL: sigma 0.2 m).
        max_range: sensor range (m), for the ``z_rand / max_range`` floor.
        max_dist: cap of the wall distance (m), AMCL's ``laser_likelihood_max_dist`` (2 m).
        temper: exponent on each scan's likelihood (< 1: neighbouring beams are not independent
            and the untempered product makes the cloud collapse on the first plausible mode).
        resample_ess: resample when ESS < ``resample_ess * n_particles``.
        off_map: log-weight penalty (nats) of a particle whose last move crossed a wall or left
            the building (Thrun's ``motion_model_with_map``; finite, so that a cloud wholly
            off the map still has weights; 0 disables it, as in AMCL).
        recovery_alpha_slow, recovery_alpha_fast: augmented MCL (AMCL's names): decay rates of
            the long- and short-term averages of the scan likelihood; when the short one falls
            below the long one, that fraction of particles restarts uniformly at resampling.
            ``recovery_alpha_fast = 0`` disables it (AMCL's default) and removes it from the
            program (so switching it on or off recompiles; other values do not).
        chunk: at most this many runs filtered together in one call (the largest divisor of
            the run count not above it; bounds memory; results do not depend on it).
    """

    n_particles: int = 8192
    n_beams: int = 60
    alpha: tuple[float, float, float, float] = (0.05, 0.05, 0.05, 0.05)
    sigma_hit: float = 0.2
    z_hit: float = 0.9
    z_rand: float = 0.1
    max_range: float = 40.0
    max_dist: float = 2.0
    temper: float = 0.05
    resample_ess: float = 0.5
    off_map: float = 20.0
    recovery_alpha_slow: float = 0.01
    recovery_alpha_fast: float = 0.1
    chunk: int = 8

    def __post_init__(self):
        for name in ("n_particles", "n_beams", "chunk"):
            v = getattr(self, name)
            if not (isinstance(v, int | np.integer) and v > 0):
                raise ValueError(f"MCLParams.{name} must be a positive int, got {name}={v!r}")
        if len(self.alpha) != 4 or not all(a >= 0 for a in self.alpha):
            raise ValueError(f"MCLParams.alpha must be 4 values >= 0, got alpha={self.alpha!r}")
        if not self.off_map >= 0:
            raise ValueError(f"MCLParams.off_map must be >= 0, got {self.off_map!r}")
        for name in ("sigma_hit", "max_range", "max_dist", "temper"):
            if not getattr(self, name) > 0:
                raise ValueError(f"MCLParams.{name} must be > 0, got {getattr(self, name)!r}")
        if not (self.z_hit >= 0 and self.z_rand > 0):
            raise ValueError(
                f"MCLParams needs z_hit >= 0 and z_rand > 0, got {self.z_hit=}, {self.z_rand=}"
            )
        if not 0 <= self.resample_ess <= 1:
            raise ValueError(f"MCLParams.resample_ess must be in [0, 1], got {self.resample_ess!r}")
        if not 0 <= self.recovery_alpha_slow <= self.recovery_alpha_fast <= 1:
            raise ValueError(
                "MCLParams needs 0 <= recovery_alpha_slow <= recovery_alpha_fast <= 1, got "
                f"{self.recovery_alpha_slow=}, {self.recovery_alpha_fast=}"
            )

    def static(self) -> dict:
        """The static parameters, as the jitted filter's keyword arguments."""
        return dict(
            n=int(self.n_particles),
            n_beams=int(self.n_beams),
            recovery=bool(self.recovery_alpha_fast > 0),
            chunk=int(self.chunk),
        )

    def traced(self) -> dict:
        """The traced parameters as float32 arrays (the jitted filter's argument)."""
        f = lambda v: jnp.asarray(v, jnp.float32)  # noqa: E731
        return dict(
            alpha=f(self.alpha),
            sigma_hit=f(self.sigma_hit),
            z_hit=f(self.z_hit),
            z_rand=f(self.z_rand),
            max_range=f(self.max_range),
            max_dist=f(self.max_dist),
            temper=f(self.temper),
            resample_ess=f(self.resample_ess),
            off_map=f(self.off_map),
            alpha_slow=f(self.recovery_alpha_slow),
            alpha_fast=f(self.recovery_alpha_fast),
        )
