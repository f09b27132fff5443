"""A window's decision passes: every lane's decision (``rule``, the certification where a lane
needs it, the early tests, the commit machine) and, where the primary lane is about to enter
COMMIT, the global search for rivals and the decision again with them (``decided``, the
robot's form; ``decided_batched``, the same for ``vmap`` over runs). ``layer.update`` calls
one of them once per window."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mfcl_jax.decision import certify, machine, rivals, rule, uniqueness
from mfcl_jax.decision.history import History
from mfcl_jax.decision.outcome import COMMIT, Decision
from mfcl_jax.decision.state import World
from mfcl_jax.sparse_cond import sparse_cond

__all__ = ["decided", "decided_batched", "where_tree"]


def where_tree(c, a, b):
    return jax.tree.map(lambda x, y: jnp.where(c, x, y), a, b)


def _certify(ops):
    world, h, c, riv, riv_ok = ops
    ev = (h.ev_points, h.ev_origins, h.ev_mask)
    return rule.certify_core(h.n - 1, c, h.H, h.score, h.X, ev, (h.start, h.end), world.maps,
                             world.params, riv, riv_ok, world.caps.cert_slots)  # fmt: skip


def _decide(world: World, h: History, cores, held, riv, riv_ok, uniq=None,
            gstat=None):  # fmt: skip
    """Every lane's decision at the newest window, given the rivals: certification where
    needed, the rule, the early tests' commit where a lane reads one
    (``early``: uniqueness, evidence grid), the commit machine. Returns ``(held,
    reported)``."""
    k = h.n - 1
    p, ln = world.params, world.lanes
    modes = world.spec.modes
    sym_of_mode = jnp.asarray([m[1] for m in modes], jnp.int32)

    def mode_of(tree, m):
        return jax.tree.map(lambda a: a[m], tree)

    need = jax.vmap(
        lambda m, ug, uc, bm, hl: rule.needs_certificate(mode_of(cores, m), p, ug, uc, bm, hl)
    )(ln.mode, ln.use_gate, ln.use_cert, ln.b_min, held)
    need_mode = jnp.any((ln.mode[None, :] == jnp.arange(len(modes))[:, None]) & need[None], 1)
    certs = jax.vmap(
        lambda n, c: sparse_cond(n, _certify, (world, h, c, riv, riv_ok)), in_axes=(0, 0)
    )(need_mode, cores)
    newest = (h.H[k], h.score[k], h.mask[k], h.X[k])
    uniq = uniqueness.skipped() if uniq is None else uniq
    gstat = uniqueness.skipped() if gstat is None else gstat

    def lane(m, ug, up, uc, bm, dm, mg, hl, nd, uu, ut, gu, gt):
        sym = mode_of(world.maps.sym, sym_of_mode[m])
        # a lane reads the certificate only where it needs one itself, so what it reports
        # does not depend on which other lanes share the evaluation
        ct = mode_of(certs, m)
        ct = certify.CertStats(ct.anchor, ct.valid, ct.max_adv, ct.min_adv, ct.n_windows,
                               ct.ran & nd)  # fmt: skip
        raw = rule.finish(mode_of(cores, m), ct, sym, p, ug, up, uc, bm, dm, mg)
        # the path is explained by one placement and no other: commit to it, whatever the
        # count of windows (the rule's own commit stands where the test does not hold)
        # a lane reads one early test: the uniqueness test or the evidence grid
        t = jax.tree.map(lambda a, b: jnp.where(gu, a, b), gstat, uniq)
        reads = (uu | gu) & t.ran
        holds = reads & ~t.vetoed & (t.llr >= jnp.where(gu, gt, ut))
        early_ = holds & (raw.state != COMMIT) & ~hl.committed
        raw = Decision(**{**raw.__dict__,
            "state": jnp.where(early_, COMMIT, raw.state),
            "kind": jnp.where(early_, 0, raw.kind),
            "reason": jnp.where(early_, 0, raw.reason),
            "anchor": jnp.where(early_, t.anchor, raw.anchor),
            "tau": jnp.where(early_, 0.0, raw.tau),
            "has_competitor": raw.has_competitor & ~early_,
            # the ratio where the test ran and no veto held (-inf: vetoed), for reading
            "llr": jnp.where(reads, jnp.where(t.vetoed, -jnp.inf, t.llr), raw.llr),
            "test_anchor": jnp.where(reads, t.anchor, raw.test_anchor),
        })  # fmt: skip
        return machine.step(hl, raw, newest, p, ug)

    return jax.vmap(lane)(ln.mode, ln.use_gate, ln.use_probe, ln.use_cert, ln.b_min,
                          ln.delta_min, ln.cert_margin, held, need,
                          ln.use_unique, ln.unique_llr, ln.use_grid, ln.grid_margin)  # fmt: skip


def _decide_pass(ops):
    """``_decide`` of one pass of ``update`` (its operands as one pytree: ``sparse_cond``)."""
    world, h, cores, held, riv, riv_ok, uniq, gstat = ops
    return _decide(world, h, cores, held, riv, riv_ok, uniq, gstat)


def _search(ops):
    """The rival search on the history, written into the run's next rival slots."""
    world, h, riv, riv_ok, searches = ops
    rp = world.rival_params
    found, ok = rivals.search(h.ev_points, h.ev_origins, h.ev_mask, h.X, world.fields,
                              world.n_img, rp)  # fmt: skip
    at = searches * rp.n_rivals
    riv = jax.lax.dynamic_update_slice(riv, found.astype(riv.dtype), (at, 0))
    return riv, jax.lax.dynamic_update_slice(riv_ok, ok, (at,))


def _search_at_commit(ops, out, riv, riv_ok, searches, go):
    """The rival search where ``go`` and the primary lane is about to enter COMMIT (searches
    left): ``(rivals, rivals_ok, searches, searched)``."""
    world, h, _, held0 = ops[:4]
    pl = world.spec.primary
    enter = (out.state[pl] == COMMIT) & ~held0.committed[pl]
    do = go & enter & (searches < world.rival_params.max_searches)
    found = sparse_cond(do, _search, (world, h, riv, riv_ok, searches))
    riv, riv_ok = where_tree(do, found, (riv, riv_ok))
    return riv, riv_ok, searches + do.astype(jnp.int32), do


def decided(ops, searches, valid):
    """Every lane's decision, with the rivals of a search where the primary lane is about to
    enter COMMIT (and searches are left): ``(rivals, rivals_ok, searches, searched, held,
    out)``. Pass 0 decides; pass 1 decides again with the rivals found, in the rows that
    searched only (``sparse_cond``). A loop: the program holds one copy of the decision."""
    world, h, cores, held0, riv, riv_ok, uniq, gstat = ops
    pl = world.spec.primary

    def one_pass(i, carry):
        riv, riv_ok, searches, searched, held, out = carry
        allow = (i == 0) | searched
        again = sparse_cond(allow, _decide_pass, (world, h, cores, held0, riv, riv_ok, uniq,
                                                  gstat), dense=True)  # fmt: skip
        held, out = where_tree(allow, again, (held, out))
        if pl >= 0:
            riv, riv_ok, searches, do = _search_at_commit(ops, out, riv, riv_ok, searches,
                                                          (i == 0) & valid)  # fmt: skip
            searched = searched | do
        return riv, riv_ok, searches, searched, held, out

    shape = jax.eval_shape(_decide_pass, ops)[1]
    zeros = jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype), shape)
    carry = (riv, riv_ok, searches, jnp.bool_(False), held0, zeros)
    return jax.lax.fori_loop(0, 2 if pl >= 0 else 1, one_pass, carry)


def decided_batched(ops, searches, valid):
    """``decided`` for ``vmap`` over runs: the two decisions written out (pass 1 under
    ``sparse_cond``), not looped, which a batch runs faster (no conditional around pass 0);
    the program holds the decision twice (longer to compile: a robot does not use it)."""
    world, h, cores, held0, riv, riv_ok, uniq, gstat = ops
    pl = world.spec.primary
    held, out = _decide_pass(ops)
    searched = jnp.bool_(False)
    if pl >= 0:
        riv, riv_ok, searches, searched = _search_at_commit(ops, out, riv, riv_ok, searches, valid)
        again = sparse_cond(searched, _decide_pass, (world, h, cores, held0, riv, riv_ok, uniq,
                                                     gstat))  # fmt: skip
        held, out = where_tree(searched, again, (held, out))
    return riv, riv_ok, searches, searched, held, out
