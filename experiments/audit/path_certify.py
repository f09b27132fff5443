"""Is there ANY placement of the path, away from the best one, that explains it nearly as well?

A branch and bound on the path's log-likelihood ``L`` (``path_llr``) over every heading and
every translation, on the cell bounds of ``path_bound`` (cells, bounds and clusters are defined
there).

Search. The exhaustive level bounds every heading (cells of ``2 delta``, ``delta`` such that
the path's farthest point moves ``turn_m`` at most) and every translation (a 0.2 m grid over
the plan grid grown by the path's radius: farther out every sample is off the grid and ``L``
is its least value ``L_min``) at once, one FFT correlation per heading of the path's images
(two radius bands, returns and free samples) with the bound fields. Each later level halves
``h`` and ``delta`` (8 children per cell) and keeps the cells whose bound reaches ``tau`` and
that are not wholly inside ``A*``'s neighbourhood (the same answer, judged where the robot is
now, as the uniqueness test judges it); past ``levels`` it goes on while few cells are left.
At every level the centres of the ``probe`` cells of highest bound are evaluated exactly (a
competitor found ends the search), and at the last level every survivor's centre.

Outcomes: ``certified`` (no cell survives: every placement outside the neighbourhood scores
below ``tau``), ``competitor`` (a placement outside the neighbourhood reaches ``tau``),
``open`` (the search could not tell within its budget: too many cells at one heading or one
level, survivors at the finest level, or ``tau <= L_min``). The search runs on the host,
level by level, over jitted batches of cells; its cost grows with the building's area and the
share of placements the bound cannot rule out (``experiments.audit.certificate``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from scipy import ndimage

from experiments.audit.path_bound import EPS, SQ2, BoundFields, cell_bounds, solid, voxels
from mfcl_jax.frontend import path_llr
from mfcl_jax.frontend.path_fields import PlanFields
from mfcl_jax.frontend.path_llr import LLRParams, PathEvidence
from mfcl_jax.frontend.path_search import fft_size
from mfcl_jax.se2 import wrap_host

__all__ = ["BoundParams", "BoundResult", "certify"]


@dataclass(frozen=True)
class BoundParams:
    """Settings of the branch and bound (one setting for every building)."""

    turn_m: float = 0.1  # m: the exhaustive level's heading cells move the path's farthest
    max_delta_deg: float = 1.0  # point by at most this much (and are at most 2 deg wide)
    keep_per_heading: int = 8192  # surviving translations one heading may hold; more: open
    fft_slack: float = 0.05  # the exhaustive level keeps cells within this of tau (float32)
    cell_slack: float = 0.005  # later levels likewise (direct sums, smaller rounding)
    levels: int = 3  # halvings after the exhaustive level (0.2 m grid): 1.25 cm
    max_levels: int = 7  # more halvings while at most ``deep_cells`` cells are left
    deep_cells: int = 50_000
    max_cells: int = 1_000_000  # cells one level may hold; more: open
    probe: int = 256  # cells whose centres are evaluated exactly at each level
    chunk: int = 4096  # cells per kernel call
    near_xy: float = 1.0  # m: the neighbourhood of A* (as ``uniqueness.UniqueParams``)
    near_deg: float = 5.0


DEFAULT_BOUND = BoundParams()
# a cell's 8 children: offsets of their centres in units of their half-sizes (h, h, delta)
_CHILDREN = np.asarray([[dx, dy, dt] for dx in (-1, 1) for dy in (-1, 1) for dt in (-1, 1)])
DEFAULT_LLR = LLRParams()


@dataclass(frozen=True)
class BoundResult:
    """What the search found: the outcome, the best exact competitor (if any) and its cost."""

    outcome: str  # "certified" | "competitor" | "open"
    why: str
    competitor: np.ndarray | None  # (3,) a placement (standard form) reaching tau
    competitor_llr: float  # L(competitor); -inf without one
    cells: int  # cells bounded, all levels (the exhaustive level counts every cell)
    levels: int  # levels searched
    seconds: float


@partial(jax.jit, static_argnames=("n_img", "out_shape", "fft_shape", "keep"))
def _exhaustive(thetas, qp, wp, bp, qf, wf, bf_, spectra, g, n_img: int, out_shape,
                fft_shape, keep: int, tau):  # fmt: skip
    """Level A: every heading of ``thetas`` and every translation of the grid at once (FFT
    correlation of the rotated path's images, one per radius band, with the bound fields
    whose spectra are ``spectra (4, ...)``: returns in bands 0, 1, free samples in bands 0,
    1). Returns, per heading, the first ``keep`` shifts whose bound reaches ``tau``, their
    bounds and their count."""
    ci = n_img // 2
    sy, sx = out_shape

    def splat(q, w, band, b):
        iu = jnp.round(q[:, 0] / g).astype(jnp.int32) + ci
        iv = jnp.round(q[:, 1] / g).astype(jnp.int32) + ci
        ok = (band == b) & (w > 0)
        img = jnp.zeros((n_img * n_img,), jnp.float32)
        return img.at[jnp.where(ok, iv * n_img + iu, 0)].add(jnp.where(ok, w, 0.0))

    def one(th):
        c, s = jnp.cos(th), jnp.sin(th)
        rot = lambda q: jnp.stack([c * q[:, 0] - s * q[:, 1], s * q[:, 0] + c * q[:, 1]], -1)  # noqa: E731
        rp, rf = rot(qp), rot(qf)
        imgs = jnp.stack([splat(rp, wp, bp, 0), splat(rp, wp, bp, 1), splat(rf, wf, bf_, 0),
                          splat(rf, wf, bf_, 1)]).reshape(4, n_img, n_img)  # fmt: skip
        spec = jnp.sum(spectra * jnp.conj(jnp.fft.rfft2(imgs, fft_shape)), axis=0)
        corr = jnp.fft.irfft2(spec, fft_shape)[:sy, :sx]
        hit = corr >= tau
        iy, ix = jnp.nonzero(hit, size=keep, fill_value=-1)
        return jnp.stack([iy, ix], -1), corr[iy, ix], jnp.sum(hit)

    return jax.lax.map(one, thetas)


def _standard(cells, c):
    """Cells' centre placements ``(u0, theta0)`` in standard form ``(t, theta)``."""
    th = cells[:, 2]
    ct, st = np.cos(th), np.sin(th)
    tx = cells[:, 0] - (ct * c[0] - st * c[1])
    ty = cells[:, 1] - (st * c[0] + ct * c[1])
    return np.stack([tx, ty, th], 1)


def _level_a(pts_c, pw, free_c, fw, bf: BoundFields, radius, tau, p: BoundParams, llr):
    """The exhaustive level: ``((cells (N, 3), bounds (N,), h, delta), counted)``, or a
    reason it is open in place of the tuple."""
    g = 2 * bf.res
    delta = min(math.radians(p.max_delta_deg), p.turn_m / max(radius, 1e-3))
    n_th = int(math.ceil(math.pi / delta))
    delta = math.pi / n_th
    thetas = -math.pi + delta * (2 * np.arange(n_th) + 1)
    # fields padded by twice the path's radius: placements whose centre lies farther than the
    # radius off the grid leave every sample off it (there ``L`` is its least value)
    m = int(math.ceil((2 * radius + 4 * g) / bf.res))
    E = np.pad(bf.capped, m, constant_values=bf.cap)
    bad = np.pad(solid(bf.bad), m, constant_values=bool(solid(bf.outside)))
    T = ndimage.distance_transform_edt(bad) * bf.res if (~bad).any() else np.full(bad.shape, 1e6)
    E, T = E[::2, ::2], T[::2, ::2]
    z0 = bf.origin - m * bf.res + 0.5 * bf.res  # node (0, 0) of the strided grid
    r_band = np.asarray([radius / 2, radius])
    rho = SQ2 * g + r_band * delta + EPS  # cell half-side g/2, nearest-node splat g/sqrt(2)
    slack = rho + SQ2 * bf.res
    f = lambda d: np.log((1 - llr.z_rand) * np.exp(-d * d / (2 * llr.sigma**2)) + llr.z_rand)  # noqa: E731
    fields4 = np.stack([f(np.maximum(E - slack[0], 0)), f(np.maximum(E - slack[1], 0)),
                        np.where(T > slack[0], math.log(1 - llr.z_block), 0.0),
                        np.where(T > slack[1], math.log(1 - llr.z_block), 0.0)])  # fmt: skip
    n_img = int(2 * math.ceil((radius + g) / g) + 1)
    ny, nx = E.shape
    out_shape = (ny - n_img + 1, nx - n_img + 1)
    fft_shape = (fft_size(ny), fft_size(nx))
    spectra = jnp.fft.rfft2(jnp.asarray(fields4, jnp.float32), fft_shape)
    bp = (np.hypot(*pts_c.T) > radius / 2).astype(np.int32)
    bfree = (np.hypot(*free_c.T) > radius / 2).astype(np.int32)
    idx, val, cnt = _exhaustive(jnp.asarray(thetas, jnp.float32), pts_c.astype(np.float32),
                           pw.astype(np.float32), bp, free_c.astype(np.float32),
                           fw.astype(np.float32), bfree, spectra, jnp.float32(g), n_img,
                           out_shape, fft_shape, p.keep_per_heading,
                           jnp.float32(tau - p.fft_slack))  # fmt: skip
    idx, val, cnt = np.asarray(idx), np.asarray(val), np.asarray(cnt)
    counted = len(thetas) * out_shape[0] * out_shape[1]
    if (cnt > p.keep_per_heading).any():
        return f"over {p.keep_per_heading} cells at one heading", counted
    j, k = np.nonzero(idx[:, :, 0] >= 0)
    iy, ix = idx[j, k, 0], idx[j, k, 1]
    ci = n_img // 2
    u = z0 + np.stack([ix + ci, iy + ci], 1) * g
    return (np.column_stack([u, thetas[j]]), val[j, k], g / 2, delta), counted


def certify(pe: PathEvidence, fields: PlanFields, bf: BoundFields, a_star, x_now,
            tau: float, p: BoundParams = DEFAULT_BOUND,
            llr: LLRParams = DEFAULT_LLR) -> BoundResult:  # fmt: skip
    """The branch and bound (module docstring) for the path evidence ``pe``.

    Args:
        pe: ``PathEvidence`` (odometry frame); fields, bf: the plan (``PlanFields``,
            ``bound_fields`` of them); a_star: ``(3,)`` the best placement (standard form);
        x_now: ``(3,)`` the robot's odometry pose (where the neighbourhood is judged);
        tau: the level a competitor must reach (``L(A*) - log(1 / alpha)``).
    """
    t0 = time.perf_counter()
    pts, pw = np.asarray(pe.pts, np.float64), np.asarray(pe.pw, np.float64)
    free, fw = np.asarray(pe.free, np.float64), np.asarray(pe.fw, np.float64)

    def done(out, why, n, lv, comp=None, lc=-math.inf):
        return BoundResult(out, why, comp, lc, n, lv, time.perf_counter() - t0)

    if not (pw > 0).any():
        return done("open", "no returns", 0, 0)
    c = (pts[pw > 0] * pw[pw > 0, None]).sum(0) / pw[pw > 0].sum()
    pts_c, free_c = pts - c, free - c
    l_min = pw.sum() * math.log(llr.z_rand) + fw.sum() * math.log(1.0 - llr.z_block)
    if tau <= l_min + 1e-6:
        return done("open", "tau at the least score", 0, 0)
    radius = float(np.max(np.hypot(*np.concatenate([pts_c[pw > 0], free_c[fw > 0]]).T)))
    # in steps of 1.6 m (8 cells of the exhaustive level): paths of about the same extent
    # share the exhaustive level's shapes, so one compilation serves them
    radius = 1.6 * math.ceil(radius / 1.6 + 1e-9)
    a_star = np.asarray(a_star, np.float64)
    x_now = np.asarray(x_now, np.float64)
    ca, sa = math.cos(a_star[2]), math.sin(a_star[2])
    star_now = a_star[:2] + [ca * x_now[0] - sa * x_now[1], sa * x_now[0] + ca * x_now[1]]
    r_now = float(np.hypot(*(x_now[:2] - c)))
    near_rad = math.radians(p.near_deg)

    def inside(cl, h, delta):
        """Cells wholly inside A*'s neighbourhood."""
        th = cl[:, 2]
        px = np.cos(th) * (x_now[0] - c[0]) - np.sin(th) * (x_now[1] - c[1]) + cl[:, 0]
        py = np.sin(th) * (x_now[0] - c[0]) + np.cos(th) * (x_now[1] - c[1]) + cl[:, 1]
        dxy = np.hypot(px - star_now[0], py - star_now[1]) + SQ2 * h + r_now * delta
        dth = np.abs(wrap_host(th - a_star[2])) + delta
        return (dxy <= p.near_xy) & (dth <= near_rad)

    def exact(cand):
        """``L`` of placements (standard form), -inf inside A*'s neighbourhood."""
        L = np.asarray(jax.vmap(lambda a: path_llr.log_likelihood(a, pe, fields, llr))(
            jnp.asarray(cand, jnp.float32)))  # fmt: skip
        cn, sn = np.cos(cand[:, 2]), np.sin(cand[:, 2])
        px = cand[:, 0] + cn * x_now[0] - sn * x_now[1]
        py = cand[:, 1] + sn * x_now[0] + cn * x_now[1]
        far = (np.hypot(px - star_now[0], py - star_now[1]) > p.near_xy) | (
            np.abs(wrap_host(cand[:, 2] - a_star[2])) > near_rad
        )
        return np.where(far, L, -np.inf)

    def _probe(cells, ub):
        """A competitor among the centres of the ``probe`` cells of highest bound, or None:
        a competitor ends the search early, whatever the cells left."""
        sel = cells[np.argsort(-ub)]
        cand = _standard(sel[: p.probe], c)
        n = len(cand)
        if n == 0:
            return None
        pad = np.concatenate([cand, np.repeat(cand[:1], p.probe - n, 0)])
        L = exact(pad)[:n]
        j = int(np.argmax(L))
        return (cand[j], float(L[j])) if L[j] >= tau else None

    level_a, total = _level_a(pts_c, pw, free_c, fw, bf, radius, tau, p, llr)
    if isinstance(level_a, str):
        return done("open", level_a, total, 1)
    cells, ub, h, delta = level_a
    hit = _probe(cells, ub)
    if hit is not None:
        return done("competitor", "", total, 1, *hit)
    f32 = jnp.float32
    consts = (jnp.asarray(bf.capped), jnp.asarray(bf.to_free), jnp.asarray(bf.bad), f32(bf.outside),
              jnp.asarray(bf.origin, f32), f32(bf.res), f32(bf.cap), f32(llr.sigma),
              f32(llr.z_rand), f32(llr.z_block))  # fmt: skip

    def bounds(cells, h, delta):
        """``cell_bounds`` of any number of cells, in padded chunks of ``p.chunk``."""
        side = h if h > 0.02 else 0.0  # the finest levels read every sample
        pq, pwv, pr = voxels(pts_c, pw, side)
        fq, fwv, fr = voxels(free_c, fw, side)
        ub = np.empty(len(cells), np.float32)
        for i in range(0, len(cells), p.chunk):
            m = min(p.chunk, len(cells) - i)
            blk = np.zeros((p.chunk, 3), np.float32)
            blk[:m] = cells[i : i + m]
            out = cell_bounds(blk, f32(h), f32(delta), pq, pwv, pr, fq, fwv, fr, *consts)
            ub[i : i + m] = np.asarray(out)[:m]
        return ub

    cells = cells[~inside(cells, h, delta)]
    if len(cells) == 0:
        return done("certified", "", total, 1)
    level = 0
    for level in range(1, p.max_levels + 1):
        if level > p.levels and len(cells) > p.deep_cells:
            level -= 1
            break
        h, delta = h / 2, delta / 2
        cells = (cells[:, None, :] + _CHILDREN * np.asarray([h, h, delta])).reshape(-1, 3)
        cells = cells[~inside(cells, h, delta)]
        if len(cells) > p.max_cells:
            return done("open", f"{len(cells)} cells at level {level}", total, level)
        ub = bounds(cells, h, delta)
        total += len(cells)
        keep = ub >= tau - p.cell_slack
        cells, ub = cells[keep], ub[keep]
        if len(cells) == 0:
            return done("certified", "", total, level + 1)
        hit = _probe(cells, ub)
        if hit is not None:
            return done("competitor", "", total, level + 1, *hit)
    # the survivors' centres, exactly
    cand = _standard(cells, c)
    L = exact(cand)
    j = int(np.argmax(L))
    if L[j] >= tau:
        return done("competitor", "", total, level + 1, cand[j], float(L[j]))
    return done("open", f"{len(cells)} cells at the last level", total, level + 1)
