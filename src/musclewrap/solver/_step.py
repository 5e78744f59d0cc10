"""The cage's contact step: a small quadratic programme in the conditions' dual space."""

from __future__ import annotations

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ..constants import defaults

__all__ = ["cage_push"]


@numba.njit(cache=True)
def _deepest_one_kernel(gap, group, size):  # noqa: ANN001, ANN202 # pragma: no cover
    # per group (0 <= group < size) the row of the smallest gap, the earlier on a tie (a
    # NaN only where the group has nothing else), in the order of the groups
    best = np.empty(size, dtype=np.int64)
    for g in range(size):
        best[g] = -1
    for i in range(gap.shape[0]):
        g = group[i]
        b = best[g]
        if b < 0 or gap[i] < gap[b] or (gap[b] != gap[b] and gap[i] == gap[i]):
            best[g] = i
    count = 0
    for g in range(size):
        if best[g] >= 0:
            count += 1
    out = np.empty(count, dtype=np.int64)
    count = 0
    for g in range(size):
        if best[g] >= 0:
            out[count] = best[g]
            count += 1
    return out


def _deepest_per_group(gap: FloatArray, group: IntArray, k: int) -> IntArray:
    """The rows of the ``k`` smallest gaps in each group, by group (ties: the earlier row)."""
    if k == 1 and len(gap) and 0 <= group.min() and group.max() < 4 * len(gap) + 1024:
        # one a group, the groups a cage's vertices: one compiled pass, no sort
        return _deepest_one_kernel(
            np.ascontiguousarray(gap, dtype=np.float64),
            np.ascontiguousarray(group, dtype=np.int64),
            int(group.max()) + 1,
        )
    order = np.lexsort((gap, group))
    start = np.ones(len(order), dtype=bool)
    start[1:] = group[order[1:]] != group[order[:-1]]
    at = np.arange(len(order))
    rank = at - np.maximum.accumulate(np.where(start, at, 0))
    return order[rank < k]


def held_choice(
    held: tuple[IntArray, FloatArray, FloatArray, FloatArray], group: IntArray
) -> IntArray:
    """Which of the ``held`` conditions a step takes: the least rank of each group.

    ``held`` as `cage_push`'s, ``group`` a group per fine vertex. A later try's held
    conditions extend the earlier's (`Deformer._stepped_in`): where they choose the same
    rows, the step they give is the one given before, bit for bit.
    """
    hr, _, _, rank = held
    return _deepest_per_group(rank, group[hr], 1)


def held_changed(
    before: tuple[IntArray, FloatArray, FloatArray, FloatArray] | None,
    after: tuple[IntArray, FloatArray, FloatArray, FloatArray],
    group: IntArray,
) -> bool:
    """Whether ``after`` (``before`` extended) chooses other conditions than ``before``."""
    return before is None or not np.array_equal(
        held_choice(before, group), held_choice(after, group)
    )


def cage_push(
    W: FloatArray,
    Hinv: FloatArray,
    g: FloatArray,
    Hg: FloatArray,
    idx: IntArray,
    gap: FloatArray,
    N: FloatArray,
    group: IntArray,
    *,
    slack: float,
    max_sets: int = 4,
    points: tuple[FloatArray, FloatArray, FloatArray] | None = None,
    own: bool = False,
    held: tuple[IntArray, FloatArray, FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """The cage displacement of least energy that takes fine vertices off the obstacles.

    Linearised non-penetration conditions ``n_i . (W_i dx) >= slack - gap_i``
    on the fine vertices ``idx`` (one per ``group``, the deepest: a cage of a
    few hundred vertices cannot follow more), with the linearised volume
    ``g . dx = 0``, minimising ``dx^T H dx`` (the growth of the shape and
    skeleton energy): a small active-set QP in the constraints' dual space,
    where ``H^-1`` is at hand. Vertices too near start active; a constraint
    that pulls (negative multiplier) leaves, a near vertex the step would push
    in joins, for at most ``max_sets`` active sets.

    Parameters
    ----------
    W : (n, m) float64 array
        Fine coordinates.
    Hinv : (m, m) float64 array
        Inverse of ``A^T A``.
    g, Hg : (m, 3) float64 arrays
        The volume gradient in cage space and ``H^-1 g``.
    idx, gap, N : arrays
        From `contact_candidates`.
    group : (n,) int array
        A group per fine vertex (its dominant cage vertex).
    slack : float
        How far beyond the margin the active vertices are taken.
    points : (Wp, gap, N), optional
        Conditions on points of the surface other than its vertices, each a row
        of coordinates ``Wp`` (k, m) (a point of a triangle: its vertices' rows
        weighted by its barycentric coordinates), its gap and its direction:
        ``n . (Wp dx) >= slack - gap`` (where an obstacle's vertex stands inside
        the muscle, the muscle's nearest point goes past it). After the vertices'
        one per group, the deepest ``defaults.contact_points_per_cage_vertex`` per
        cage vertex with the largest weight in their rows.
    own : bool, optional
        Soften each condition by ``defaults.contact_softness`` times its own diagonal
        of the conditions' Gram matrix, not the mean diagonal of all: a stiff one (a
        vertex the cage moves only at a high energy, pinned by its line) is met as far
        as a supple one (the later steps of a call, ``defaults.contact_stiff_from``).
    held : (rows, gap, N, rank), optional
        Vertex conditions as ``idx``, ``gap``, ``N`` that do not compete with those
        for their group's one place: one a group of their own (the least ``rank``)
        joins the pool beside it. What a first try of the step put into a bone where
        a deeper condition held the group's place (`Deformer._stepped_in`).

    Returns
    -------
    (m, 3) float64 array
        ``dx`` (zeros when no vertex is too near).
    """
    m = Hinv.shape[0]
    extra = points is not None and len(points[0]) > 0
    if (not len(idx) or gap.min() >= 0) and not extra:
        return np.zeros((m, 3))
    # one candidate per group: the nearest (most negative gap)
    pool = _deepest_per_group(gap, group[idx], 1)
    rows, r, Nn = idx[pool], slack - gap[pool], N[pool]
    if held is not None and len(held[0]):
        hr, hg, hn, _ = held
        hp = held_choice(held, group)
        rows = np.concatenate([rows, hr[hp]])
        r = np.concatenate([r, slack - hg[hp]])
        Nn = np.vstack([Nn, hn[hp]])
    Wr = W[rows]
    if extra:
        assert points is not None
        Wp, gp, Np = points
        # the deepest few per cage vertex that dominates them (many of another muscle's
        # vertices can stand in this one: a dense system of thousands)
        keep = _deepest_per_group(
            gp, np.argmax(np.abs(Wp), axis=1), defaults.contact_points_per_cage_vertex
        )
        Wp, gp, Np = Wp[keep], gp[keep], Np[keep]
        Wr = np.vstack([Wr, Wp])
        r = np.concatenate([r, slack - gp])
        Nn = np.vstack([Nn, Np])
    Y = Wr @ Hinv  # (k, m): W_i H^-1
    c = np.einsum("ij,ij->i", Nn, Wr @ Hg)
    # soft conditions: a cage of a few hundred vertices cannot meet many close ones exactly,
    # and the exact least-energy step of nearly dependent ones is huge; the fine finish
    # takes what the cage leaves. The scale: the mean of the Gram matrix's diagonal over
    # every candidate (the matrix itself only ever over the active set)
    diag = np.einsum("ij,ij->i", Y, Wr) * np.einsum("ij,ij->i", Nn, Nn)
    soft = defaults.contact_softness * float(np.mean(diag))
    gg = float(np.sum(g * Hg))  # g . H^-1 g
    active = r > 0
    dx = np.zeros((m, 3))
    for _ in range(max_sets):
        a = np.flatnonzero(active)
        if not len(a):
            break
        k = len(a)
        M = np.empty((k + 1, k + 1))
        M[:k, :k] = (Y[a] @ Wr[a].T) * (Nn[a] @ Nn[a].T)
        M[:k, k] = M[k, :k] = c[a]
        M[k, k] = gg
        M[np.arange(k), np.arange(k)] += defaults.contact_softness * diag[a] if own else soft
        rhs = np.append(r[a], 0.0)
        try:
            sol = np.linalg.solve(M, rhs)
        except np.linalg.LinAlgError:
            sol = np.linalg.lstsq(M, rhs, rcond=1e-12)[0]
        mu, mu_v = sol[:k], sol[k]
        dx = Y[a].T @ (mu[:, None] * Nn[a]) + mu_v * Hg
        lin = np.einsum("ij,ij->i", Nn, Wr @ dx)
        join = ~active & (lin < r - slack)
        leave = np.zeros_like(active)
        leave[a] = mu < 0
        if not join.any() and not leave.any():
            break
        active = (active | join) & ~leave
    return dx
