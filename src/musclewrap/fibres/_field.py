"""Fibres at rest as streamlines of a harmonic field, carried by the cage (issue 14, part 1-2).

Following Choi & Blemker (2013, "Skeletal muscle fascicle arrangements can be reconstructed
using a Laplacian vector field simulation", PLoS ONE 8(10): e77576): a scalar field ``u`` with
``Laplace(u) = 0`` inside the muscle, ``u = 0`` on the origin's attachment area, ``u = 1`` on
the insertion's and no flux through the rest of the surface; fibres follow its gradient from
one area to the other. Here the field is solved by finite differences on a regular grid of the
muscle's inside (generalized winding numbers decide inside), the fibres are traced from seeds
spread over the half-way level ``u = 1/2`` in both directions, and each fibre point gets its
mean value coordinates in the rest cage: a deformation's cage positions then carry the fibres
exactly as they carry the surface (`Fibres.at`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray

if TYPE_CHECKING:
    from ..solver import Muscle

__all__ = ["Fibres", "attachment_areas", "fibres_at_rest"]


@dataclass(frozen=True)
class Fibres:
    """Fibres of one muscle at rest, and how the cage carries them.

    Attributes
    ----------
    points : (N, K, 3) float64 array
        Rest positions, origin end first.
    W : (N * K, m) float64 array
        Mean value coordinates of the points in the rest cage.
    origin, insertion : int64 arrays
        The surface vertices of the attachment areas the field was solved between.
    spacing : float
        The grid spacing of the field (mesh units).
    """

    points: FloatArray
    W: FloatArray
    origin: IntArray
    insertion: IntArray
    spacing: float

    def at(self, cage: npt.ArrayLike) -> FloatArray:
        """The fibres' points for deformed cage positions ``cage`` (``DeformationResult.cage``)."""
        X = np.asarray(cage, dtype=np.float64)
        if X.shape != (self.W.shape[1], 3):
            raise ValueError(f"cage has shape {X.shape}, the fibres' cage has {self.W.shape[1]}")
        return (self.W @ X).reshape(self.points.shape)

    def lengths(self, points: npt.ArrayLike | None = None) -> FloatArray:
        """(N,) length of each fibre (its poly-line), at rest or for ``points`` from `at`."""
        P = self.points if points is None else np.asarray(points, dtype=np.float64)
        return np.linalg.norm(np.diff(P, axis=1), axis=2).sum(axis=1)


def attachment_areas(
    V: FloatArray, lines: Mapping[str, npt.ArrayLike], reach: float = 0.1
) -> tuple[IntArray, IntArray]:
    """The surface vertices where the muscle attaches: its two ends along its action lines.

    The axis runs from the centroid of the lines' first points (the origin) to that
    of their last points (the insertion); the origin's area is the vertices in the
    first ``reach`` of the mesh's extent along it, the insertion's those in the last.
    The mesh's own ends, not the lines' points: a model's path may start well inside
    the segmented muscle (the LHDL psoas's starts 124 mm below the top of its mesh,
    10 mm off its surface), and the fibres run the muscle's whole length.

    Parameters
    ----------
    V : (n, 3) float64 array
        Rest vertices, in the frame of ``lines``.
    lines : mapping of str to (p, 3) array_like
        Rest action lines.
    reach : float, optional
        Fraction of the mesh's extent along the axis.

    Returns
    -------
    origin, insertion : sorted int64 arrays

    Raises
    ------
    ValueError
        If there are no lines, or their ends coincide (no axis).
    """
    paths = [np.asarray(p, dtype=np.float64) for p in lines.values()]
    if not paths:
        raise ValueError("no action lines: the attachments are not known")
    axis = np.mean([p[-1] for p in paths], axis=0) - np.mean([p[0] for p in paths], axis=0)
    norm = float(np.linalg.norm(axis))
    if not norm > 0:
        raise ValueError("the action lines start and end at the same place: no axis")
    if not 0 < reach < 0.5:
        raise ValueError(f"reach must lie between 0 and 0.5, got {reach}")
    t = V @ (axis / norm)
    lo, hi = float(t.min()), float(t.max())
    span = hi - lo
    return np.flatnonzero(t <= lo + reach * span), np.flatnonzero(t >= hi - reach * span)


def fibres_at_rest(
    muscle: Muscle,
    lines: Mapping[str, npt.ArrayLike],
    *,
    count: int = 100,
    points: int = 15,
    reach: float = 0.1,
    voxels: int = 60_000,
    origin: npt.ArrayLike | None = None,
    insertion: npt.ArrayLike | None = None,
    seed: int = 0,
) -> Fibres:
    """Fibres of a prepared muscle from its origin to its insertion.

    Parameters
    ----------
    muscle : musclewrap.Muscle
        The prepared muscle (its fine rest mesh and cage).
    lines : mapping of str to (p, 3) array_like
        Rest action lines (the attachments, unless given).
    count : int, optional
        Number of fibres N.
    points : int, optional
        Points per fibre K (evenly spaced along it).
    reach : float, optional
        Attachment areas (`attachment_areas`).
    voxels : int, optional
        About how many grid cells lie inside the muscle (the field's resolution).
    origin, insertion : int array_like, optional
        The attachment areas as surface vertex indices, instead of from the lines.
    seed : int, optional
        Seeds the choice among equally good starting points (the result is deterministic).

    Returns
    -------
    Fibres

    Raises
    ------
    ValueError
        If an attachment area is empty, the areas are not connected through the inside
        of the muscle, or fewer than ``count`` fibres stay inside it.
    """
    import igl
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import laplacian
    from scipy.sparse.linalg import LinearOperator, cg
    from scipy.spatial import cKDTree

    from ..conditions import polyline_at
    from ..coordinates import mean_value_coordinates

    V = np.asarray(muscle.V, dtype=np.float64)
    F = np.asarray(muscle.F, dtype=np.int64)
    cage = muscle.cage
    if count < 1 or points < 2:
        raise ValueError(f"need count >= 1 and points >= 2, got {count} and {points}")
    if origin is None or insertion is None:
        o, i = attachment_areas(V, lines, reach)
        origin = o if origin is None else origin
        insertion = i if insertion is None else insertion
    org = np.unique(np.asarray(origin, dtype=np.int64))
    ins = np.unique(np.asarray(insertion, dtype=np.int64))
    if not len(org) or not len(ins):
        raise ValueError("an attachment area is empty")

    # --- the grid over the muscle and its inside
    lo, hi = V.min(axis=0), V.max(axis=0)
    vol = float(abs(muscle.volume_rest))
    h = (vol / voxels) ** (1.0 / 3.0)
    shape = np.ceil((hi - lo) / h).astype(int) + 3
    origin_pt = lo - h
    idx = np.indices(shape).reshape(3, -1).T
    centres = origin_pt + (idx + 0.5) * h
    inside = (igl.fast_winding_number(V, F, centres) > 0.5).reshape(shape)

    # --- Dirichlet cells: inside cells within 1.5 h of an attachment vertex
    ins_idx = np.flatnonzero(inside.ravel())
    tree = cKDTree(centres[ins_idx])
    fixed = np.full(inside.size, np.nan)
    for verts, value in ((org, 0.0), (ins, 1.0)):
        near = tree.query_ball_point(V[verts], 1.5 * h)
        cells = np.unique(np.concatenate([np.asarray(c, dtype=np.int64) for c in near]))
        if not len(cells):  # a thin muscle: the nearest inside cell of each vertex
            cells = np.unique(tree.query(V[verts])[1])
        fixed[ins_idx[cells]] = value
    # the component(s) of the inside that touch both areas
    labels, _ = ndimage.label(inside)
    lab = labels.ravel()
    both = np.intersect1d(
        np.unique(lab[np.flatnonzero(fixed == 0.0)]), np.unique(lab[np.flatnonzero(fixed == 1.0)])
    )
    both = both[both > 0]
    if not len(both):
        raise ValueError("the origin and insertion areas are not connected inside the muscle")
    domain = np.isin(lab, both)

    # --- the harmonic field: 7-point Laplacian, no flux where a neighbour is outside
    cells = np.flatnonzero(domain)
    number = np.full(inside.size, -1)
    number[cells] = np.arange(len(cells))
    strides = np.array([shape[1] * shape[2], shape[2], 1])
    rows, cols = [], []
    for ax in range(3):
        for sgn in (-1, 1):
            c3 = idx[cells, ax] + sgn
            ok = (c3 >= 0) & (c3 < shape[ax])
            nb = cells[ok] + sgn * strides[ax]
            ok2 = domain[nb]
            rows.append(number[cells[ok][ok2]])
            cols.append(number[nb[ok2]])
    r, c = np.concatenate(rows), np.concatenate(cols)
    n = len(cells)
    L = laplacian(coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)).tocsr()).tocsr()
    val = fixed[cells]
    known = ~np.isnan(val)
    free = np.flatnonzero(~known)
    u = np.where(known, val, 0.0)
    if len(free):
        # conjugate gradients with the diagonal as preconditioner: the matrix is the
        # grid's graph Laplacian with the attachment cells removed (positive definite on
        # the domain, which touches both); a direct solve took 6.5 s at 60K cells, this 0.2
        rhs = -L[free][:, np.flatnonzero(known)] @ val[known]
        Lff = L[free][:, free].tocsr()
        dinv = 1.0 / Lff.diagonal()
        M = LinearOperator(Lff.shape, matvec=lambda x: dinv * x, dtype=np.float64)
        sol, info = cg(Lff, rhs, rtol=1e-10, atol=0.0, maxiter=20 * len(free), M=M)
        if info != 0:
            raise ValueError(f"the fibres' field did not converge (conjugate gradients: {info})")
        u[free] = sol
    U = np.full(inside.size, np.nan)
    U[cells] = u
    # outside the domain: the value of the nearest domain cell (a gradient without a wall)
    _, near_idx = ndimage.distance_transform_edt(~domain.reshape(shape), return_indices=True)
    U = U.reshape(shape)[tuple(near_idx)]
    dom3 = domain.reshape(shape)
    G = np.stack(np.gradient(U, h), axis=0)

    def sample(grid: FloatArray, P: FloatArray) -> FloatArray:
        q = ((P - origin_pt) / h - 0.5).T
        return ndimage.map_coordinates(grid, q, order=1, mode="nearest")

    def direction(P: FloatArray) -> FloatArray:
        g = np.stack([sample(G[k], P) for k in range(3)], axis=1)
        norm = np.linalg.norm(g, axis=1)
        return g / np.where(norm > 0, norm, np.inf)[:, None]

    def trace(S: FloatArray, sign: float, stop: float) -> list[FloatArray]:
        # all seeds at once, midpoint steps of h / 2 along +-grad u, each until u passes stop
        P = S.copy()
        path = [P.copy()]
        steps = np.zeros(len(S), dtype=int)
        active = np.ones(len(S), dtype=bool)
        step = 0.5 * h
        for _ in range(int(20 * shape.max())):
            a = np.flatnonzero(active)
            if not len(a):
                break
            d1 = direction(P[a])
            d2 = direction(P[a] + 0.5 * step * sign * d1)
            moving = np.linalg.norm(d2, axis=1) > 0
            active[a[~moving]] = False
            a = a[moving]
            Q = P[a] + step * sign * d2[moving]
            # a step that leaves the field's cells ends the fibre where it was (a thin
            # tendon may hold no cell: the fibre ends at the last one, on the surface)
            cell = np.clip(np.floor((Q - origin_pt) / h).astype(int), 0, shape - 1)
            out = ~dom3[cell[:, 0], cell[:, 1], cell[:, 2]]
            active[a[out]] = False
            a, Q = a[~out], Q[~out]
            P[a] = Q
            steps[a] += 1
            uu = sample(U, P[a])
            active[a[uu >= stop if sign > 0 else uu <= stop]] = False
            path.append(P.copy())
        T = np.array(path)
        return [T[: steps[j] + 1, j] for j in range(len(S))]

    # --- seeds spread over the half-way level (farthest-point sampling)
    k = min(len(u), max(8 * count, 400))
    cand = centres[cells[np.argsort(np.abs(u - 0.5))[:k]]]
    rng = np.random.default_rng(seed)
    order = [int(rng.integers(len(cand)))]
    dist = np.linalg.norm(cand - cand[order[0]], axis=1)
    while len(order) < min(len(cand), 2 * count):
        j = int(np.argmax(dist))
        order.append(j)
        dist = np.minimum(dist, np.linalg.norm(cand - cand[j], axis=1))
    S = cand[order]
    backs = trace(S, -1.0, 1e-3)
    fwds = trace(S, 1.0, 1.0 - 1e-3)
    whole = []
    for back, fwd in zip(backs, fwds, strict=True):
        line = np.concatenate([back[::-1], fwd[1:]])
        ends = sample(U, line[[0, -1]]) if len(line) >= 3 else np.array([1.0, 0.0])
        if ends[0] <= 0.05 and ends[1] >= 0.95:  # else it stopped short of an attachment
            whole.append(polyline_at(line, np.linspace(0.0, 1.0, points)))
    inside_all = np.zeros(0, dtype=bool)
    if whole:
        w = igl.fast_winding_number(V, F, np.concatenate(whole))
        inside_all = (w > 0.5).reshape(len(whole), points).all(axis=1)
    if inside_all.sum() < count:
        raise ValueError(
            f"only {int(inside_all.sum())} of {count} fibres stay inside the muscle: "
            "use more voxels"
        )
    P = np.array(whole)[np.flatnonzero(inside_all)[:count]]
    W = mean_value_coordinates(P.reshape(-1, 3), cage.C, cage.CF)
    return Fibres(points=P, W=W, origin=org, insertion=ins, spacing=float(h))
