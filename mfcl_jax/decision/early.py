"""The early-commit tests as one update runs them: a lane may commit, whatever the count of
windows, where the path is explained by one placement and by no other.

* the uniqueness test (``uniqueness``): a fresh search and fit of the whole path, at most
  ``UniqueParams.max_tests`` times per odometry segment;
* the evidence grid (``grid``): every placement's accumulated log-likelihood, grown by each
  window's scans, read at every window.

Both answer with ``uniqueness.UniqStats`` and share the layer's vetoes
(``uniqueness.vetoes``); both skip the windows where no lane still needs them (a batch pays
only for those, ``sparse_cond``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import grid as G
from mfcl_jax.decision import uniqueness
from mfcl_jax.sparse_cond import sparse_cond

__all__ = ["champion", "unique_test", "grid_test"]


def champion(h, c):
    """The newest window's champion (its best admitted candidate) and whether it has one."""
    k = h.n - 1
    adm = c.admitted[k]
    j = jnp.argmax(jnp.where(adm, h.score[k], -jnp.inf))
    return h.H[k, j], jnp.any(adm)


def _contradicted(champ, c0, p):
    """A consensus winner of two or more windows that the newest champion disagrees with."""
    cxy, cth = se2.distance_pair(champ, c0.groups.t_star)
    apart = (cxy > p.delta_xy) | (cth > p.delta_theta)
    return (c0.groups.b1 >= 2) & apart


def _unique(ops):
    world, h, path, c = ops
    g, pr = c.groups, c.probe_result
    champ, champ_ok = champion(h, c)
    p = world.params
    return uniqueness.uniqueness(
        h, path, world.maps, world.fields, world.n_img, g.t_star, pr.aliases, pr.aliases_ok,
        champ, champ_ok, g.b1.astype(jnp.float32), p.tau_c, p.delta_xy, p.delta_theta,
    )  # fmt: skip


def unique_test(world, h, path, c0, u_tests, open_lane, valid):
    """The uniqueness test where a lane still needs it: ``(stats, u_tests)``."""
    p = world.params
    need = open_lane & (u_tests < uniqueness.DEFAULT_UNIQUE.max_tests) & valid
    # the vetoes that need no search, checked first
    champ, champ_ok = champion(h, c0)
    need = need & champ_ok & ~_contradicted(champ, c0, p)
    stats = sparse_cond(need, _unique, (world, h, path, c0))
    return stats, u_tests + need.astype(jnp.int32)


def _grid(ops):
    world, g, h, path, c0, ev = ops
    g = G.add_window(g, world.fields, ev.X, path.dist, ev.ev_points, ev.ev_origins, ev.ev_mask)
    lead = G.lead(g, world.fields, ev.X)
    champ, champ_ok = champion(h, c0)
    p = world.params
    X = ev.X.astype(champ.dtype)

    def near(a):  # anchor ``a`` and the leader, judged where the robot is now
        dxy, dth = se2.distance_pair(se2.compose(a, X), lead.pose)
        return (dxy <= p.delta_xy) & (dth <= p.delta_theta)

    # the newest window's champion must be the leader; the commit is to the consensus
    # winner where it is the leader too (a mean of windows, steadier than one registration)
    t_star = c0.groups.t_star
    anchor = jnp.where(near(t_star), t_star, champ)
    b1 = c0.groups.b1.astype(jnp.float32)
    vetoed, c_gate = uniqueness.vetoes(anchor, path, world.maps, champ, champ_ok, t_star, b1,
                                       p.tau_c, p.delta_xy, p.delta_theta)  # fmt: skip
    stats = uniqueness.UniqStats(
        anchor,
        lead.competitor,
        lead.margin,
        vetoed | ~(champ_ok & near(champ)),
        c_gate,
        jnp.bool_(True),
    )
    return g, stats


def grid_test(world, g, h, path, c0, ev, open_lane):
    """The evidence grid grown by the window ``ev`` and read, where a lane still needs it:
    ``(grid, stats)``: the anchor a lane commits to (the consensus winner where it is the
    grid's leader, else the newest window's champion, which must be), the leader's margin."""
    need = open_lane & ev.valid
    new, stats = sparse_cond(need, _grid, (world, g, h, path, c0, ev))
    # skipped (every grid lane committed): the grid stays as it was
    return jax.tree.map(lambda a, b: jnp.where(need, a, b), new, g), stats
