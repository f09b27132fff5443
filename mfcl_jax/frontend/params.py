"""Front-end settings (``FrontendParams``, all static: a change recompiles) and the XLA
options every compiled front-end call uses."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FrontendParams", "COMPILER_OPTIONS"]


# XLA:CPU options for every compiled front-end call: fast math with NaN, Inf, division and
# library-function semantics kept, which leaves reassociation (and FMA contraction). Strict
# IEEE order keeps a loop that accumulates sums scalar; reassociated, XLA vectorises it:
# the refinement's nine running sums per point get 3.5x faster. Results move by rounding.
COMPILER_OPTIONS = {
    "xla_cpu_enable_fast_math": True,
    "xla_cpu_fast_math_honor_infs": True,
    "xla_cpu_fast_math_honor_nans": True,
    "xla_cpu_fast_math_honor_division": True,
    "xla_cpu_fast_math_honor_functions": True,
}


@dataclass(frozen=True)
class FrontendParams:
    """Front-end settings (all static). Distances in metres, angles in degrees."""

    J: int = 32  # candidates returned per submap (<= n_hough)
    min_points: int = 50  # fewer valid points -> reason 2
    # line Hough over a strided subsample
    hough_points: int = 768
    line_theta_bins: int = 90
    line_rho_res: float = 0.10
    rho_max: float = 20.0
    n_lines: int = 16
    line_nms_deg: float = 4.0
    line_nms_rho: float = 0.35
    inlier_band: float = 0.10
    min_line_pts: int = 12
    min_line_frac: float = 0.02
    # corners
    corner_min_angle_deg: float = 30.0
    arm_min: float = 0.10
    arm_max: float = 1.50
    min_arm_pts: int = 5
    n_corners: int = 32
    corner_angle_tol_deg: float = 6.0
    # pose accumulator (evaluated at the votes)
    cell: float = 0.15
    yaw_bin_deg: float = 1.0
    nms_xy: float = 0.45
    nms_deg: float = 3.0
    max_votes: int = 2048
    n_hough: int = 64  # peaks that get the full score
    # prescreen: every accumulator peak (up to n_prescreen) scored on a small subsample
    n_prescreen: int = 256
    prescreen_points: int = 96
    # verification: continuous score (bilinear signed distance), see verify.py
    verify_points: int = 512
    ray_samples: int = 2
    ray_stop: float = 0.30
    sigma_occ: float = 0.07
    sigma_free: float = 0.05
    lambda_free: float = 1.0
    # refinement of the top J: optax, Gauss-Newton-preconditioned steps (refine.py),
    # sigma_refine -> sigma_occ; the heading is optimised in metres of arc at yaw_lever
    refine_points: int = 512
    refine_steps: int = 10
    sigma_refine: float = 0.30
    refine_max_step: float = 0.2  # per step, metres (of arc at yaw_lever for the heading)
    yaw_lever: float = 5.0
    # first-round adam learning rate: name kept so old configs still parse; setting it is an error
    refine_lr: float | None = None
    # final de-duplication of refined candidates
    dedupe_xy: float = 0.30
    dedupe_deg: float = 2.0
    # dense correlative hypotheses (dense.py), added to the accumulator peaks; 0 turns them off
    dense_n: int = 24  # polished dense peaks per submap
    dense_img: int = 96  # submap image side (coarse cells) of the correlation
    dense_res: float = 0.4  # coarse cell (m), rounded to a multiple of the raster cell
    dense_sub_dirs: int = 2  # submap wall directions
    dense_plan_dirs: int = 3  # plan wall directions
    dense_peaks_per_yaw: int = 3
    dense_lam: float = 1.0  # weight of the obstacle penalty (as the rival search)
    dense_polish_points: int = 128

    def __post_init__(self):
        if self.refine_lr is not None:
            raise ValueError(
                f"FrontendParams: refine_lr={self.refine_lr!r} is no longer used "
                "(refinement steps are Gauss-Newton-preconditioned, no learning "
                "rate); use refine_steps, sigma_refine, refine_max_step, yaw_lever"
            )
        if self.dense_n < 0 or self.dense_lam < 0:
            raise ValueError(
                f"FrontendParams: need dense_n >= 0 and dense_lam >= 0, got {self.dense_n=}, "
                f"{self.dense_lam=}"
            )
        if not 1 <= self.J <= self.n_hough <= self.n_prescreen <= self.max_votes:
            raise ValueError(
                "FrontendParams: need 1 <= J <= n_hough <= n_prescreen <= max_votes, got "
                f"{self.J=}, {self.n_hough=}, {self.n_prescreen=}, {self.max_votes=}"
            )
        for name in (
            "hough_points",
            "n_lines",
            "n_corners",
            "max_votes",
            "verify_points",
            "refine_points",
            "ray_samples",
            "prescreen_points",
            "refine_steps",
            "dense_img",
            "dense_sub_dirs",
            "dense_plan_dirs",
            "dense_peaks_per_yaw",
            "dense_polish_points",
        ):
            if getattr(self, name) < 1:
                raise ValueError(f"FrontendParams: {name} must be >= 1, got {getattr(self, name)}")
        for name in (
            "cell",
            "line_rho_res",
            "rho_max",
            "inlier_band",
            "sigma_occ",
            "sigma_free",
            "sigma_refine",
            "refine_max_step",
            "yaw_lever",
            "dense_res",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"FrontendParams: {name} must be > 0, got {getattr(self, name)}")
