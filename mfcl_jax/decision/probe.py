"""Alias probe: re-gate period-shifted and rotated copies of the winner.

Translational aliases are ``T* + n tau`` (floor-plan-frame translation, orientation kept) for
``n = +-1..+-n_max`` and every probe period: the lattice period detected over all groups (when
one is found) and the floor plan's fundamental congruent-room offsets, so an image that the
front-end's tie-breaking kept out of the champions can still block a commit. Rotational
aliases are ``g T*`` (composed in SE(2): the whole anchored trajectory carried by ``g``) for
every rotational self-motion ``g`` of the building (``DecisionMaps.motions``, see ``symmetry``).
An alias of either kind is admissible iff it passes the gate (``c >= tau_c``) and
``c >= c_winner - gamma``; translational ones are reported first.

The winner itself is gated in the same batched call, and its rooms spanned read from the same
labels, so the probe costs one label lookup and one counting pass (``gate.walk_labels``) of
``1 + 2 P n_cap + M`` anchors over the trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax import se2
from mfcl_jax.decision import gate as gate_mod

__all__ = ["ProbeResult", "probe"]


@dataclass(frozen=True)
class ProbeResult:
    c_winner: jax.Array  # () consistency of T*
    rooms: jax.Array  # () int32 rooms spanned by the trajectory under T*
    alias: jax.Array  # () bool an admissible alias exists
    tau: jax.Array  # (2,) period of the first admissible alias (zero if none)
    c_alias: jax.Array  # () best alias consistency among the probed ones (0 if none)
    n: jax.Array  # () int32 shift count of the admissible alias (0 if none)
    rot_alias: jax.Array  # () bool an admissible rotational alias exists
    motion: jax.Array  # (3,) self-motion g of the first admissible rotational alias (zero if none)
    c_rot: jax.Array  # () best rotational alias consistency (0 if none)
    aliases: jax.Array  # (A, 3) every probed alias (shifted, then rotated)
    aliases_ok: jax.Array  # (A,) bool admissible by the gate (the certification's competitors)


jax.tree_util.register_dataclass(
    ProbeResult, data_fields=list(ProbeResult.__dataclass_fields__), meta_fields=[]
)


def probe(
    maps, sym, t_star, taus, taus_mask, traj, valid, tau_c, gamma, n_max, n_cap: int = 3
) -> ProbeResult:
    """Gates ``T*``, its period-shifted and its rotated aliases on the samples ``valid``.

    Args:
        maps: ``DecisionMaps``; sym: its ``Symmetry`` set in use (``motions`` give the
            rotational aliases).
        t_star: ``(3,)`` winner anchor.
        taus: ``(P, 2)`` probe periods; taus_mask: ``(P,)`` bool (all False: no probe).
        traj: ``(T, 3)``; valid: ``(T,)`` the samples of the prefix.
        tau_c, gamma, n_max: thresholds (traced); ``n_max <= n_cap``.
        n_cap: static number of shifts per sign.
    """
    n = jnp.concatenate([jnp.arange(1, n_cap + 1), -jnp.arange(1, n_cap + 1)])  # (2n_cap,)
    shift = n[None, :, None].astype(taus.dtype) * taus[:, None, :]  # (P, 2n_cap, 2)
    alias = jnp.concatenate(
        [t_star[:2] + shift, jnp.broadcast_to(t_star[2], shift.shape[:-1])[..., None]], axis=-1
    )
    p = taus.shape[0]
    m = sym.motions.shape[0]
    rot = se2.compose(sym.motions.astype(t_star.dtype), t_star[None])  # (M, 3) g T*
    anchors = jnp.concatenate([t_star[None], alias.reshape(-1, 3), rot], axis=0)
    label = gate_mod.labels(maps, anchors, traj)  # (A, T)
    walk = gate_mod.walk_labels(maps, label, valid, gate_mod.start_walk(anchors.shape[:1]))
    c = walk.consistency()
    rooms = jnp.arange(maps.adjacency.shape[-1] - 1, dtype=label.dtype)
    seen = jnp.any((label[0][:, None] == rooms) & valid[:, None], axis=0)
    c_win, c_alias = c[0], c[1 : 1 + p * 2 * n_cap].reshape(p, 2 * n_cap)
    c_rot = c[1 + p * 2 * n_cap :]
    rot_adm = sym.motions_mask & (c_rot >= tau_c) & (c_rot >= c_win - gamma)
    rot_found = jnp.any(rot_adm)
    g = sym.motions[jnp.argmax(rot_adm)] if m else jnp.zeros((3,), t_star.dtype)
    used = taus_mask[:, None] & (jnp.abs(n).astype(jnp.float32) <= n_max)[None, :]
    adm = used & (c_alias >= tau_c) & (c_alias >= c_win - gamma)
    found = jnp.any(adm)
    flat = jnp.argmax(adm.reshape(-1))
    tau = jnp.where(found, taus[flat // (2 * n_cap)], jnp.zeros((2,), taus.dtype))
    return ProbeResult(
        c_winner=c_win,
        rooms=jnp.sum(seen).astype(jnp.int32),
        alias=found,
        tau=tau,
        c_alias=jnp.max(jnp.where(used, c_alias, 0.0)),
        n=jnp.where(found, n[flat % (2 * n_cap)], 0).astype(jnp.int32),
        rot_alias=rot_found,
        motion=jnp.where(rot_found, g.astype(t_star.dtype), jnp.zeros((3,), t_star.dtype)),
        c_rot=jnp.max(jnp.where(sym.motions_mask, c_rot, 0.0), initial=0.0),
        aliases=anchors[1:],
        aliases_ok=jnp.concatenate([adm.reshape(-1), rot_adm]),
    )
