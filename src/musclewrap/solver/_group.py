"""Muscles pressed against each other stepped together: one least-energy step of their cages.

The rounds of `musclewrap.solver.meet` step each muscle on its own, from the same
snapshot, each taking half of every overlap (`defaults.muscle_share`). Where a muscle
cannot take its half (a bone holds it) the other gets only its own half a round, and a
stack of muscles (the vasti round the intermedius round the femur) needs a round per
layer. Here the muscles that overlap each other in a round take one step together:
their cage displacements side by side, each overlap one condition on the two of them
(the vertex of one goes past the point of the other's surface it stands behind, by
the whole depth: who moves how far follows from the energies), each muscle's bones'
conditions and its volume beside them. The same small quadratic programme in the
conditions' dual space as `cage_push` (each muscle's ``H^-1`` at hand; a condition
on two muscles sums their parts), then each muscle's step ended on its exact fine
volume as its own steps are (`ContactSteps._end_step`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from .._typing import FloatArray, IntArray
from ..constants import defaults, tol
from ..contact import Overlap, as_placed, contact_candidates
from ._deformer import Deformer
from ._step import _deepest_per_group, held_changed, held_choice

__all__ = ["joint_round", "overlap_groups"]


def overlap_groups(names: Sequence[str], found: Mapping[str, Sequence[Overlap]]) -> list[list[str]]:
    """The muscles of ``names`` joined by an overlap among them (`overlaps`), each sorted.

    Connected components of the overlaps, in the order of their first names; a
    muscle that overlaps none of the others of ``names`` is a group of its own.
    """
    parent = {n: n for n in names}

    def root(n: str) -> str:
        while parent[n] != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    for n in names:
        for o in found.get(n, ()):
            if o.other in parent:
                a, b = sorted((root(n), root(o.other)))
                parent[b] = a
    groups: dict[str, list[str]] = {}
    for n in sorted(names):
        groups.setdefault(root(n), []).append(n)
    return [groups[k] for k in sorted(groups)]


@dataclass
class _Terms:
    """One muscle's parts of the step's conditions: rows of coordinates, directions, signs."""

    rows: list[FloatArray] = field(default_factory=list)  # (t, m) blocks
    dirs: list[FloatArray] = field(default_factory=list)  # (t, 3), the muscle's frame
    signs: list[FloatArray] = field(default_factory=list)
    cond: list[IntArray] = field(default_factory=list)  # the condition of each row

    def add(self, W: FloatArray, D: FloatArray, sign: float, cond: IntArray) -> None:
        if len(W):
            self.rows.append(W)
            self.dirs.append(D)
            self.signs.append(np.full(len(W), sign))
            self.cond.append(np.asarray(cond, dtype=np.int64))

    def stacked(self) -> tuple[FloatArray, FloatArray, FloatArray, IntArray] | None:
        if not self.rows:
            return None
        return (
            np.vstack(self.rows),
            np.vstack(self.dirs),
            np.concatenate(self.signs),
            np.concatenate(self.cond),
        )


@dataclass
class _Conditions:
    """A joint step's conditions, as gathered.

    Per muscle its parts (``terms``), the rows of its own (``own_rows``) and points of
    its surface (``other_rows``) they are on, how far any must go (``need``); per
    condition, in blocks, what it asks (``asks``), its slack and the muscle whose it is
    (``owner``); ``count`` of them.
    """

    terms: dict[str, _Terms]
    asks: list[FloatArray]
    slack: list[FloatArray]
    owner: list[IntArray]
    count: int
    own_rows: dict[str, list[IntArray]]
    other_rows: dict[str, list[FloatArray]]
    need: dict[str, float]


def _rotation(frames: Mapping[str, FloatArray | None], n: str) -> FloatArray | None:
    T = frames.get(n)
    return None if T is None else T[:3, :3]


def _to_muscle(R: FloatArray | None, D: FloatArray) -> FloatArray:
    """Directions of the common frame in a muscle's (``R``: its rotation into the common)."""
    return D if R is None else D @ R


def joint_round(
    deformers: Mapping[str, Deformer],
    state: Mapping[str, tuple[FloatArray, FloatArray]],
    surf: Mapping[str, tuple[FloatArray, IntArray]],
    found: Mapping[str, Sequence[Overlap]],
    group: Sequence[str],
    *,
    frames: Mapping[str, FloatArray | None],
    obstacles: Mapping[str, Sequence[Any] | None],
    margin: float,
    sides: Mapping[str, Any],
    nears: Mapping[str, Any],
    share: float = defaults.muscle_share,
    far: float | None = None,
) -> dict[str, tuple[FloatArray, FloatArray]]:
    """One step of the cages of the muscles ``group`` together, out of each other and their bones.

    ``state``: each muscle's cage and fine positions (its own frame); ``surf``: the
    positions in the common frame the overlaps ``found`` were found on (`overlaps`);
    ``frames[name]``: its transform into the common frame (None: the same).
    An overlap between two muscles of the group is one condition on both: the
    vertex goes past the point of the other's surface it stands behind, along the
    way out, by its whole depth (``out . (W_a dx_a - w W_b dx_b) >= depth``). An
    overlap with a muscle outside the group is this muscle's ``share`` of it, as a
    round on its own takes it; each muscle's bones as `Deformer.contact_round` takes
    them (``obstacles``, ``margin``, ``sides``, ``nears``: per muscle); ``far`` as
    `Deformer.contact_round`'s. Returns the new cage and fine positions of each muscle
    of the group (its arrays where it did not move).
    """
    names = list(group)
    pools = {
        n: _candidates(
            deformers, state, found, names, n, frames, obstacles, margin, sides, nears, share
        )
        for n in names
    }
    tried: dict[str, FloatArray] = {}
    out = _joint_step(deformers, state, surf, found, names, frames, pools, share, far, tried)
    for _ in range(defaults.contact_round_held):
        # what the step put into a bone, held (the deepest condition of each cage vertex
        # alone took its place), and the step again from where it started
        again = False
        for n in names:
            pool, obs = pools[n], obstacles.get(n)
            if pool is None or not obs or out[n] is state[n]:
                continue
            held = deformers[n]._stepped_in(
                state[n][1], out[n][1], tried[n], as_placed(obs), margin, nears.get(n),
                sides.get(n), *pool.bones, pool.held,
            )  # fmt: skip
            if held is not None:
                # a try whose held conditions choose as the last did gives its step again
                again |= held_changed(pool.held, held, deformers[n]._dominant)
                pools[n] = dataclasses.replace(pool, held=held)
        if not again:
            break
        out = _joint_step(deformers, state, surf, found, names, frames, pools, share, far, tried)
    return out


def _joint_step(
    deformers: Mapping[str, Deformer],
    state: Mapping[str, tuple[FloatArray, FloatArray]],
    surf: Mapping[str, tuple[FloatArray, IntArray]],
    found: Mapping[str, Sequence[Overlap]],
    names: Sequence[str],
    frames: Mapping[str, FloatArray | None],
    pools: Mapping[str, _Pool | None],
    share: float,
    far: float | None,
    tried: dict[str, FloatArray],
) -> dict[str, tuple[FloatArray, FloatArray]]:
    """`joint_round`'s step on the conditions of ``pools``: each muscle's new cage and vertices.

    ``tried``: each muscle's linear cage step (`_solve`'s, before its volume) put in it.
    """
    got = _select(deformers, surf, found, names, frames, pools, share, defaults.muscle_joint_points)
    if got.count > defaults.muscle_joint_conditions:
        # a large group (the dense solve costs the cube of its conditions): one a cage vertex
        got = _select(deformers, surf, found, names, frames, pools, share, 1)
    terms, r_all, slack_all, owner = got.terms, got.asks, got.slack, got.owner
    counts, own_rows, other_rows, need = got.count, got.own_rows, got.other_rows, got.need
    out = {n: state[n] for n in names}
    if not counts:
        return out
    r = np.concatenate(r_all)
    slack_c = np.concatenate(slack_all)
    dxs = _solve(deformers, state, names, terms, r, slack_c, np.concatenate(owner))
    for n in names:
        if n not in dxs:
            continue
        dx, Hg = dxs[n]
        tried[n] = dx
        d = deformers[n]
        x, V = state[n]
        idx = np.concatenate(own_rows[n]) if own_rows[n] else np.zeros(0, dtype=np.int64)
        rows = np.vstack(other_rows[n]) if other_rows[n] else None
        step = d._end_step(x, V, dx, Hg, idx, need[n], rows, far)
        if step is not None:
            out[n] = step
    return out


@dataclass
class _Pool:
    """One muscle's vertex conditions in a joint step, before they are pooled.

    Per candidate: its fine vertex ``rows``, gap ``G``, way out ``N`` (the muscle's
    frame), the overlap it came from ``S`` and its place there ``P`` (-1: no partner
    in the group), and ``lead``: the partner's cage vertex that leads the point behind
    it, numbered apart per muscle (-1: none). ``bones``: the rows and gaps of the
    bones' candidates among them; ``held``: conditions a first try of the step showed
    were needed (`Deformer._stepped_in`), beside the others.
    """

    rows: IntArray
    G: FloatArray
    N: FloatArray
    P: IntArray
    S: IntArray
    lead: IntArray
    bones: tuple[IntArray, FloatArray] = (np.zeros(0, dtype=np.int64), np.zeros(0))
    held: tuple[IntArray, FloatArray, FloatArray, FloatArray] | None = None


def _candidates(
    deformers: Mapping[str, Deformer],
    state: Mapping[str, tuple[FloatArray, FloatArray]],
    found: Mapping[str, Sequence[Overlap]],
    names: Sequence[str],
    n: str,
    frames: Mapping[str, FloatArray | None],
    obstacles: Mapping[str, Sequence[Any] | None],
    margin: float,
    sides: Mapping[str, Any],
    nears: Mapping[str, Any],
    share: float,
) -> _Pool | None:
    """Muscle ``n``'s vertex conditions before pooling; None where there are none.

    In another muscle (the whole depth where the other steps with it, else its
    ``share``) and near its bones. Found once per step, whatever the pooling.
    """
    d = deformers[n]
    edge = d._fine_edge
    slack = tol.contact * edge
    R = _rotation(frames, n)
    idx, gap, N, partner = [], [], [], []
    for o in found.get(n, ()):
        whole = o.other in names
        idx.append(o.rows)
        gap.append(slack - (o.depth if whole else share * o.depth))
        N.append(_to_muscle(R, o.out))
        partner.append(np.arange(len(o.rows)) if whole else np.full(len(o.rows), -1))
    obs = obstacles.get(n)
    bones = (np.zeros(0, dtype=np.int64), np.zeros(0))
    if obs:
        bi, bg, bn = contact_candidates(
            state[n][1], obs, margin, defaults.contact_band * edge, nears.get(n), sides.get(n)
        )
        idx.append(bi)
        gap.append(bg)
        N.append(bn)
        partner.append(np.full(len(bi), -1))
        bones = (bi, bg)
    if not idx:
        return None
    # which overlap each vertex condition came from (to find its partner's point)
    S = np.concatenate([np.full(len(a), j) for j, a in enumerate(idx)])
    P = np.concatenate(partner)
    lead = np.full(len(S), -1, dtype=np.int64)
    for j, o in enumerate(found.get(n, ())):
        sel = np.flatnonzero((S == j) & (P >= 0))
        if len(sel):
            mb = deformers[o.other].muscle
            # the cage vertex that leads the triangle's rows, numbered apart per muscle
            rows = mb.W[mb.F[o.face[P[sel]]]].sum(axis=1)
            lead[sel] = np.argmax(np.abs(rows), axis=1) + names.index(o.other) * (1 << 32)
    return _Pool(
        np.concatenate(idx).astype(np.int64), np.concatenate(gap), np.vstack(N), P, S, lead,
        bones,
    )  # fmt: skip


def _select(
    deformers: Mapping[str, Deformer],
    surf: Mapping[str, tuple[FloatArray, IntArray]],
    found: Mapping[str, Sequence[Overlap]],
    names: Sequence[str],
    frames: Mapping[str, FloatArray | None],
    pools: Mapping[str, _Pool | None],
    share: float,
    points: int,
) -> _Conditions:
    """The step's conditions from the muscles' ``pools``.

    The deepest vertex per cage vertex, and on another muscle's surface the deepest
    ``points`` per cage vertex that leads them.
    """
    terms = {n: _Terms() for n in names}
    r_all: list[FloatArray] = []  # what each condition asks for
    slack_all: list[FloatArray] = []
    owner: list[IntArray] = []  # the muscle (its place in the group) whose condition it is
    counts = 0
    own_rows: dict[str, list[IntArray]] = {n: [] for n in names}
    other_rows: dict[str, list[FloatArray]] = {n: [] for n in names}
    need = dict.fromkeys(names, 0.0)
    for k, n in enumerate(names):
        d = deformers[n]
        slack = tol.contact * d._fine_edge
        pool = pools[n]
        if pool is not None:
            keep = _deepest_per_group(pool.G, d._dominant[pool.rows], 1)
            # and, as a round on its own takes the other's vertices inside it, the deepest
            # few per cage vertex of the other muscle that leads the point behind them
            coupled = np.flatnonzero(pool.lead >= 0)
            if len(coupled):
                more = coupled[_deepest_per_group(pool.G[coupled], pool.lead[coupled], points)]
                keep = np.union1d(keep, more)
            rows_, G_, P_, S_ = pool.rows[keep], pool.G[keep], pool.P[keep], pool.S[keep]
            ids = counts + np.arange(len(rows_))
            counts += len(rows_)
            terms[n].add(d.muscle.W[rows_], pool.N[keep], 1.0, ids)
            r_all.append(slack - G_)
            slack_all.append(np.full(len(rows_), slack))
            owner.append(np.full(len(rows_), k))
            own_rows[n].append(rows_)
            need[n] = max(need[n], float((slack - G_).max(initial=0.0)))
            if pool.held is not None:
                # one a cage vertex of their own (the deepest where the trial put them)
                hr, hg, hn, _ = pool.held
                hp = held_choice(pool.held, d._dominant)
                hids = counts + np.arange(len(hp))
                counts += len(hp)
                terms[n].add(d.muscle.W[hr[hp]], hn[hp], 1.0, hids)
                r_all.append(slack - hg[hp])
                slack_all.append(np.full(len(hp), slack))
                owner.append(np.full(len(hp), k))
            # the partners' parts: the point of the other's surface behind the vertex
            for j, o in enumerate(found.get(n, ())):
                sel = np.flatnonzero((S_ == j) & (P_ >= 0))
                if o.other not in names or not len(sel):
                    continue
                at, b = P_[sel], o.other
                Wp = deformers[b].surface_rows(o.point[at], o.face[at], surf[b][0])
                Db = _to_muscle(_rotation(frames, b), o.out[at])
                terms[b].add(Wp, Db, -1.0, ids[sel])
                other_rows[b].append(Wp)
                need[b] = max(need[b], float((slack - G_[sel]).max(initial=0.0)))
        # another muscle's vertices inside this one, where that one steps apart: this
        # muscle's surface gives the rest of their depth there, as a round on its own
        R = _rotation(frames, n)
        gi, gW, gD = [], [], []
        for m in sorted(found):
            if m in names:
                continue
            for o in found[m]:
                if o.other == n and len(o.rows):
                    gi.append((1.0 - share) * o.depth)
                    gW.append(d.surface_rows(o.point, o.face, surf[n][0]))
                    gD.append(_to_muscle(R, -o.out))
        if gi:
            give, Wp, Dp = np.concatenate(gi), np.vstack(gW), np.vstack(gD)
            keep = _deepest_per_group(-give, np.argmax(np.abs(Wp), axis=1), points)
            give, Wp, Dp = give[keep], Wp[keep], Dp[keep]
            ids = counts + np.arange(len(give))
            counts += len(give)
            terms[n].add(Wp, Dp, 1.0, ids)
            r_all.append(give)
            slack_all.append(np.full(len(give), slack))
            owner.append(np.full(len(give), k))
            other_rows[n].append(Wp)
            need[n] = max(need[n], float(give.max()))
    return _Conditions(terms, r_all, slack_all, owner, counts, own_rows, other_rows, need)


def _solve(
    deformers: Mapping[str, Deformer],
    state: Mapping[str, tuple[FloatArray, FloatArray]],
    names: Sequence[str],
    terms: Mapping[str, _Terms],
    r: FloatArray,
    slack: FloatArray,
    owner: IntArray,
    max_sets: int = 4,
) -> dict[str, tuple[FloatArray, FloatArray]]:
    """The cage displacements of least total energy that meet the conditions, volumes kept.

    `cage_push`'s active-set programme with the muscles side by side: each
    muscle's ``H^-1`` for its parts of the conditions, one linearised volume
    condition per muscle. Returns per muscle with a part in them ``(dx, H^-1 g)``.
    """
    K = len(r)
    parts = {}
    for n in names:
        st = terms[n].stacked()
        if st is None:
            continue
        d = deformers[n]
        Wt, Dt, s, c = st
        g, Hg = d._volume_direction(state[n][0])
        Y = Wt @ d._Hinv
        parts[n] = (Wt, Dt, s, c, Y, Hg, float(np.sum(g * Hg)))
    order = list(parts)
    L = len(order)
    # the diagonal and the volume's column of each condition (the whole Gram matrix of
    # thousands of conditions is never formed: only the active set's, each time it changes)
    diag = np.zeros(K)
    Cv = np.zeros((K, L))
    for j, n in enumerate(order):
        Wt, Dt, s, c, Y, Hg, _ = parts[n]
        np.add.at(diag, c, np.einsum("ij,ij->i", Y, Wt) * np.einsum("ij,ij->i", Dt, Dt))
        np.add.at(Cv[:, j], c, s * np.einsum("ij,ij->i", Dt, Wt @ Hg))
    gg = np.array([parts[n][6] for n in order])
    # soft as each muscle's own step is: a share of the mean diagonal of the conditions
    # it owns (one scale for the whole group would meet a stiff pair's conditions by
    # less than their own steps do, and the rounds would crawl)
    scale = np.bincount(owner, weights=diag) / np.maximum(np.bincount(owner), 1)
    soft = defaults.contact_softness * scale[owner]
    active = r > 0
    dx = {n: np.zeros_like(parts[n][5]) for n in order}
    for _ in range(max_sets):
        a = np.flatnonzero(active)
        if not len(a):
            break
        k = len(a)
        at = np.full(K, -1)
        at[a] = np.arange(k)
        M = np.zeros((k + L, k + L))
        for n in order:
            Wt, Dt, s, c, Y, Hg, _ = parts[n]
            sel = np.flatnonzero(at[c] >= 0)
            if not len(sel):
                continue
            block = (Y[sel] @ Wt[sel].T) * (Dt[sel] @ Dt[sel].T) * np.outer(s[sel], s[sel])
            # a muscle's part of a condition comes once (its own rows, or its side of a
            # partner's): its block adds in one go
            i = at[c[sel]]
            M[np.ix_(i, i)] += block
        M[np.arange(k), np.arange(k)] += soft[a]
        M[:k, k:] = Cv[a]
        M[k:, :k] = Cv[a].T
        M[np.arange(k, k + L), np.arange(k, k + L)] = gg
        rhs = np.concatenate([r[a], np.zeros(L)])
        # the Gram matrix of the conditions and volumes under each H^-1, and the softness
        # on its diagonal: positive definite where the conditions are independent, so
        # Cholesky (half LU's work, and this solve was three quarters of a joint round)
        try:
            sol = cho_solve(cho_factor(M, check_finite=False), rhs, check_finite=False)
        except np.linalg.LinAlgError:
            sol = np.linalg.lstsq(M, rhs, rcond=1e-12)[0]
        mu = np.zeros(K)
        mu[a] = sol[:k]
        lin = np.zeros(K)
        for j, n in enumerate(order):
            Wt, Dt, s, c, Y, Hg, _ = parts[n]
            dx[n] = Y.T @ ((s * mu[c])[:, None] * Dt) + sol[k + j] * Hg
            np.add.at(lin, c, s * np.einsum("ij,ij->i", Dt, Wt @ dx[n]))
        join = ~active & (lin < r - slack)
        leave = active & (mu < 0)
        if not join.any() and not leave.any():
            break
        active = (active | join) & ~leave
    return {n: (dx[n], parts[n][5]) for n in order}
