"""An evidence grid over every placement of the robot, grown one window at a time.

The uniqueness test (``uniqueness``) asks "is the path explained by one placement and by no
other?" by searching the plan again for the whole path at every window it runs. This module
keeps the answer instead: per run, a dense array over placements of the robot *now*
(heading x position on the plan's grid, ``GridParams.yaw_step_deg`` x ``PlanFields.g_res``)
holding each placement's accumulated log-likelihood of the scans seen so far. A window adds
only its own scans; the question "who leads, and by how much over everything outside the
leader's neighbourhood?" is then a max over the array.

Shapes (``Y`` = 72 headings, ``Hg x Wg`` the plan's grid at ``g_res`` = 0.3 m, ``n`` = 128
the window image side, ``fh x fw`` the FFT size ``>= (Hg + n/2) x (Wg + n/2)``,
``path_search.corr_size``):

* state per run: ``value (Y, Hg, Wg)`` float32, ``offset (Y, 2)``, a few scalars:
  ``4 Y Hg Wg`` bytes: a 51 m square plan (171 x 171 cells) 8.4 MB, a 20,000 m^2 plan
  (141 m square, 472 x 472 cells) 64 MB;
* per window: per heading one weighted splat of the window's evidence (``P`` returns, ``4 P``
  free samples), two real FFTs of ``fh x fw`` forward and one back (the plan's two spectra
  are taken once per window, not per heading), a shift (gather) and a 3 x 3 max where the
  drift budget asks for it: about ``Y * 3 * 2.5 fh fw log2(fh fw)`` flops, 1.0 GFLOP on the
  51 m plan (fh = fw = 240).

The model is the path log-likelihood's (``frontend.path_llr``: a return's likelihood field
with a clutter floor, free samples against the plan's occupancy, one observation per metre
of travel), read on coarse fields max-pooled over a cell's reach (``plan_fields``: ``g_hit``,
``g_free``), so a cell holds about the best placement inside it, not its centre's.

Robot-centred: a cell is where the robot is now. When the robot moves by ``d`` (odometry),
every heading ``theta``'s array shifts by ``R(theta) d`` (whole cells; the remainder is kept
per heading in ``offset`` and enters the next splat). A heading on the 5 deg grid is up to
2.5 deg off the truth, so the path it shifts along drifts by up to 4.4 % of the distance;
odometry drifts too. Both enter as a dilation: a drift budget of ``drift_xy`` m per m
travelled, and ``drift_deg`` per m, is spent one cell (one heading step) at a time on a
3 x 3 max (a max over neighbouring headings): a path is not forced to be rigid, old evidence
is loosened as it ages.

The statistic (``lead``): the leader is the best cell; its margin is its value less the best
value of any cell outside its neighbourhood (farther than ``near_xy`` or ``near_deg`` from it,
the line a commit is judged by). A wide peak (a path too short to tell a 5 deg turn apart)
has its own edge outside the line, so the margin waits until the path narrows it. The margin
is in nats of the pooled model, not of ``path_llr``'s: its commit threshold is calibrated on
the benchmark's windows (``report.calibration``), not read off Wald's bound.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.frontend.path_fields import PlanFields
from mfcl_jax.frontend.path_search import corr_size

__all__ = ["GridParams", "DEFAULT_GRID", "Grid", "Lead", "empty", "add_window", "lead"]

NEG = -1.0e9  # placements ruled out (the robot came from off the plan's grid)


@dataclass(frozen=True)
class GridParams:
    """Static settings of the grid (one setting for every building)."""

    yaw_step_deg: float = 5.0
    n_img: int = 128  # window image side (cells): +-19 m about the robot at 0.3 m
    drift_xy: float = 0.06  # m of slack per m travelled (4.4 % heading grid + odometry)
    drift_deg: float = 0.5  # deg of slack per m travelled
    near_xy: float = 1.0  # m: placements this close to the leader are the same answer
    near_deg: float = 5.0
    ray_fracs: tuple = (0.3, 0.6, 0.85)  # free samples along each evidence ray

    @property
    def n_yaw(self) -> int:
        return int(round(360.0 / self.yaw_step_deg))


DEFAULT_GRID = GridParams()


@dataclass(frozen=True)
class Grid:
    """One run's grid (see the module docstring)."""

    value: jax.Array  # (Y, Hg, Wg) accumulated log-likelihood of the robot at each cell
    offset: jax.Array  # (Y, 2) where the robot sits in its cell, in cells (x, y), per heading
    last: jax.Array  # (3,) odometry pose at the last window added
    dist: jax.Array  # () odometric distance at the last window added
    budget: jax.Array  # (2,) drift slack not yet spent: (m, deg)
    spread: jax.Array  # (2,) slack spent so far (m, deg): how far the leader's peak is smeared
    n: jax.Array  # () int32 windows added


@dataclass(frozen=True)
class Lead:
    """The grid's answer at one window."""

    anchor: jax.Array  # (3,) the leader as an anchor (maps the odometry frame into the plan)
    pose: jax.Array  # (3,) the leader: the robot's placement now
    competitor: jax.Array  # (3,) the best placement outside the leader's neighbourhood (anchor)
    margin: jax.Array  # () leader's value less the competitor's (+inf with none)


for _cls in (Grid, Lead):
    jax.tree_util.register_dataclass(
        _cls, data_fields=list(_cls.__dataclass_fields__), meta_fields=[]
    )


def empty(shape, gp: GridParams = DEFAULT_GRID) -> Grid:
    """The grid before the first window, for a plan grid of ``shape (Hg, Wg)``."""
    f = jnp.float32
    return Grid(jnp.zeros((gp.n_yaw, *shape), f), jnp.zeros((gp.n_yaw, 2), f), jnp.zeros(3, f),
                f(0.0), jnp.zeros(2, f), jnp.zeros(2, f), jnp.int32(0))  # fmt: skip


def _yaws(gp: GridParams):
    return jnp.deg2rad(jnp.arange(gp.n_yaw, dtype=jnp.float32) * gp.yaw_step_deg)


def _splat(xy, w, n: int):
    """Bilinear splat of weighted points ``xy (M, 2)`` (cells, the robot at ``n // 2``) into an
    ``(n, n)`` image; points off the image are dropped."""
    u0, v0 = jnp.floor(xy[:, 0]), jnp.floor(xy[:, 1])
    fu, fv = xy[:, 0] - u0, xy[:, 1] - v0
    u0, v0 = u0.astype(jnp.int32), v0.astype(jnp.int32)
    img = jnp.zeros((n * n,), jnp.float32)
    for du, dv, k in ((0, 0, (1 - fu) * (1 - fv)), (1, 0, fu * (1 - fv)), (0, 1, (1 - fu) * fv),
                      (1, 1, fu * fv)):  # fmt: skip
        iu, iv = u0 + du, v0 + dv
        good = (iu >= 0) & (iu < n) & (iv >= 0) & (iv < n)
        img = img.at[jnp.where(good, iv * n + iu, 0)].add(jnp.where(good, w * k, 0.0))
    return img.reshape(n, n)


def _samples(ev_points, ev_origins, ev_mask, fracs):
    """The window's returns and free samples (window frame) with validity."""
    fr = jnp.asarray(fracs, ev_points.dtype)[:, None, None]
    along = (ev_origins[None] + fr * (ev_points - ev_origins)[None]).reshape(-1, 2)
    free = jnp.concatenate([along, ev_origins])
    fok = jnp.concatenate([jnp.tile(ev_mask, len(fracs)), ev_mask])
    return free, fok


def _shift(value, offset, d, gp: GridParams):
    """Moves every heading's array by the odometry step ``d (2,)`` (plan cells); the whole
    cells shift the array, the rest stays in ``offset``."""
    yaws = _yaws(gp)
    step = se2.rotate(yaws, jnp.broadcast_to(d, (gp.n_yaw, 2)))  # (Y, 2) cells
    off = offset + step
    whole = jnp.round(off)
    off = off - whole
    whole = whole.astype(jnp.int32)
    hc, wc = value.shape[1:]
    iy, ix = jnp.arange(hc), jnp.arange(wc)

    def one(v, s):
        # the robot now at cell i was at i - s
        src_y, src_x = iy - s[1], ix - s[0]
        ok = ((src_y >= 0) & (src_y < hc))[:, None] & ((src_x >= 0) & (src_x < wc))[None]
        g = v[jnp.clip(src_y, 0, hc - 1)][:, jnp.clip(src_x, 0, wc - 1)]
        return jnp.where(ok, g, NEG)

    return jax.vmap(one)(value, whole), off


def _dilate(value, xy, th):
    """A 3 x 3 max over positions where ``xy``, over neighbouring headings where ``th``."""
    v = jnp.where(xy, jax.lax.reduce_window(value, NEG, jax.lax.max, (1, 3, 3), (1, 1, 1),
                                            "SAME"), value)  # fmt: skip
    vt = jnp.maximum(v, jnp.maximum(jnp.roll(v, 1, 0), jnp.roll(v, -1, 0)))
    return jnp.where(th, vt, v)


def add_window(g: Grid, fields: PlanFields, X, dist, ev_points, ev_origins, ev_mask,
               gp: GridParams = DEFAULT_GRID) -> Grid:  # fmt: skip
    """The grid after one more window.

    Args:
        g: the grid so far; fields: the plan (its ``g_hit``, ``g_free``, ``g_res``, ``origin``).
        X: ``(3,)`` the window's odometry pose (its last scan); dist: ``()`` the odometric
            distance travelled at the window's end.
        ev_points, ev_origins: ``(P, 2)`` the window's evidence sample (window frame);
            ev_mask: ``(P,)``.
    """
    res = fields.g_res
    n = gp.n_img
    hc, wc = fields.g_hit.shape
    X = X.astype(jnp.float32)
    dist = jnp.asarray(dist, jnp.float32)
    # the robot's step since the last window, and the metres it adds
    first = g.n == 0
    d = jnp.where(first, 0.0, 1.0) * (X[:2] - g.last[:2]) / res
    value, offset = _shift(g.value, g.offset, d, gp)
    metres = jnp.maximum(dist - jnp.where(first, 0.0, g.dist), 0.0)
    budget = g.budget + metres * jnp.asarray([gp.drift_xy, gp.drift_deg], jnp.float32)
    unit = jnp.asarray([res, gp.yaw_step_deg], jnp.float32)
    spend = (budget >= unit) & ~first
    value = _dilate(value, spend[0], spend[1])
    budget = jnp.where(spend, budget - unit, budget)
    spread = g.spread + jnp.where(spend, unit, 0.0)
    # the window's returns and free samples, each set weighing its metres of travel
    free, fok = _samples(ev_points, ev_origins, ev_mask, gp.ray_fracs)
    count = lambda m: jnp.maximum(jnp.sum(m), 1).astype(jnp.float32)  # noqa: E731
    wp = jnp.where(ev_mask, metres / count(ev_mask), 0.0)
    wf = jnp.where(fok, metres / count(fok), 0.0)
    fh, fw = corr_size(hc, n), corr_size(wc, n)
    F_hit = jnp.fft.rfft2(fields.g_hit, (fh, fw))
    F_free = jnp.fft.rfft2(fields.g_free, (fh, fw))
    c = n // 2

    def one(th, off):
        R = se2.rotate(th + X[2], ev_points) / res + off + c
        Rf = se2.rotate(th + X[2], free) / res + off + c
        spec = F_hit * jnp.conj(jnp.fft.rfft2(_splat(R, wp, n), (fh, fw))) + F_free * jnp.conj(
            jnp.fft.rfft2(_splat(Rf, wf, n), (fh, fw))
        )
        sc = jnp.fft.irfft2(spec, (fh, fw))
        # sc[s] = sum_v img[v] field[v + s]; the robot (image cell c) at plan cell i: s = i - c
        return jnp.roll(sc, (c, c), (0, 1))[:hc, :wc]

    add = jax.lax.map(lambda a: one(*a), (_yaws(gp), offset))
    base = metres * (fields.g_off[0] + fields.g_off[1])  # every sample off the plan
    value = jnp.maximum(value + add + base, NEG)
    return Grid(value, offset, X, dist, budget, spread, g.n + 1)


def _poses(g: Grid, fields: PlanFields, X, gp: GridParams):
    """The robot's placement at every cell: ``(x, y)`` of shape ``(Y, Hg, Wg)`` and the
    heading ``(Y,)``."""
    res = fields.g_res
    hc, wc = g.value.shape[1:]
    f = jnp.float32
    x = fields.origin[0] + (jnp.arange(wc, dtype=f)[None, None] + 0.5
                            + g.offset[:, 0, None, None]) * res  # fmt: skip
    y = fields.origin[1] + (jnp.arange(hc, dtype=f)[None, :, None] + 0.5
                            + g.offset[:, 1, None, None]) * res  # fmt: skip
    return x, y, _yaws(gp) + X[2]


def _peaks(value):
    """Cells at least as high as their 3 x 3 neighbours on their heading and the same cell on
    the two neighbouring headings: the tops of the grid's hills."""
    m = jax.lax.reduce_window(value, NEG, jax.lax.max, (1, 3, 3), (1, 1, 1), "SAME")
    m = jnp.maximum(m, jnp.maximum(jnp.roll(value, 1, 0), jnp.roll(value, -1, 0)))
    return value >= m


def lead(g: Grid, fields: PlanFields, X, gp: GridParams = DEFAULT_GRID) -> Lead:
    """The leader, its best competitor and the margin between them (``X``: the odometry pose
    of the robot now, the last window's).

    A competitor is the top of another hill (``_peaks``) outside the leader's neighbourhood
    widened by the drift slack spent so far (``Grid.spread``): the dilation smears the
    leader's own peak that far, so nearer cells are its own slope, not another answer."""
    X = X.astype(jnp.float32)
    x, y, th = _poses(g, fields, X, gp)
    flat = g.value.reshape(-1)
    i = jnp.argmax(flat)
    ti, yi, xi = jnp.unravel_index(i, g.value.shape)
    px, py, pt = x[ti, yi, xi], y[ti, yi, xi], th[ti]
    dth = jnp.abs(se2.angle_diff(th, pt))
    far_th = dth > jnp.deg2rad(gp.near_deg + g.spread[1]) + 1e-4
    far = (jnp.hypot(x - px, y - py) > gp.near_xy + g.spread[0]) | far_th[:, None, None]
    other = jnp.where(far & _peaks(g.value), g.value, NEG).reshape(-1)
    j = jnp.argmax(other)
    tj, yj, xj = jnp.unravel_index(j, g.value.shape)
    inv = se2.inverse(X)
    pose = jnp.stack([px, py, pt])
    comp = jnp.stack([x[tj, yj, xj], y[tj, yj, xj], th[tj]])
    none = other[j] <= NEG / 2
    margin = jnp.where(none, jnp.inf, flat[i] - other[j])
    return Lead(se2.compose(pose, inv), pose, se2.compose(comp, inv), margin)
