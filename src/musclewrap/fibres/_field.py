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

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from ..mesh import vertex_normals, winding_numbers

if TYPE_CHECKING:
    from ..solver import Muscle

__all__ = [
    "Fibres",
    "HarmonicField",
    "areas_on_bones",
    "attachment_areas",
    "fibres_at_rest",
    "harmonic_field",
    "keep_inside",
    "trace_fibres",
]


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
    share : (N,) float64 array
        Each fibre's share of the muscle's cross-section where it is widest (the field's
        level of most cells): the cells of that level nearer its seed than any other
        fibre's (shares sum to 1). Equal shares where unknown.
    area : (N,) float64 array
        Each fibre's cross-section: its share of the muscle's volume over its mean fibre
        length at rest (the physiological cross-section, without pennation), mesh
        units squared: weights for its force or moment arm.
    """

    points: FloatArray
    W: FloatArray
    origin: IntArray
    insertion: IntArray
    spacing: float
    share: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(0))
    area: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(0))

    def at(self, cage: npt.ArrayLike) -> FloatArray:
        """The fibres' points for deformed cage positions ``cage`` (``DeformationResult.cage``)."""
        X = np.asarray(cage, dtype=np.float64)
        if X.shape != (self.W.shape[1], 3):
            raise ValueError(f"cage has shape {X.shape}, the fibres' cage has {self.W.shape[1]}")
        from ..coordinates import rows_dot

        # the compiled row products: W @ X through BLAS took 10x as long in a worker process
        return rows_dot(self.W, X).reshape(self.points.shape)

    def lengths(self, points: npt.ArrayLike | None = None) -> FloatArray:
        """(N,) length of each fibre (its poly-line), at rest or for ``points`` from `at`."""
        if points is None:
            return self.rest_lengths
        P = np.asarray(points, dtype=np.float64)
        return np.linalg.norm(np.diff(P, axis=1), axis=2).sum(axis=1)

    @cached_property
    def rest_lengths(self) -> FloatArray:
        """(N,) the fibres' lengths at rest (computed once)."""
        return np.linalg.norm(np.diff(self.points, axis=1), axis=2).sum(axis=1)


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


def areas_on_bones(
    V: FloatArray,
    F: IntArray,
    lines: Mapping[str, npt.ArrayLike],
    on_origin: npt.ArrayLike | None,
    on_insertion: npt.ArrayLike | None,
    *,
    reach: float = 0.1,
    least: int | None = None,
    end_reach: float | None = None,
    end_part: float | None = None,
) -> tuple[IntArray, IntArray, tuple[str, str]]:
    """The attachment areas where the muscle lies on the bones of its ends' bodies.

    ``on_origin``: per vertex, whether it lies on a bone of the body the lines start
    in (at rest; None where the scene has no such bone); ``on_insertion`` the same for
    the body they end in. The origin's area is those vertices in the part of the
    muscle on the origin's side (``end_part`` of its extent along the axis of
    `attachment_areas`, ``defaults.fibre_area_end_part``), in patches
    (connected on the mesh ``V, F``) that come within ``end_reach`` of a path's length
    (``defaults.fibre_area_end_reach``) of that path's first point; the insertion's
    the same with the other end and the last points. A muscle lies on bones where it
    does not attach: on a bone of its origin's body further on (the psoas over the
    pelvic brim, 0.65-0.84 of its extent) or over a joint it crosses (the iliacus on the
    femur's head, 55 mm from where its path ends: far from the end). Where a side
    keeps fewer than ``least`` vertices (``defaults.fibre_area_least``), its end cap
    (`attachment_areas` with ``reach``).

    Returns
    -------
    origin, insertion : sorted int64 arrays
    rules : (str, str)
        Per side, ``"bones"`` or ``"ends"``: which rule gave it.
    """
    from scipy.sparse.csgraph import connected_components

    from ..constants import defaults
    from ..mesh import vertex_adjacency

    least = defaults.fibre_area_least if least is None else least
    end_reach = defaults.fibre_area_end_reach if end_reach is None else end_reach
    caps = attachment_areas(V, lines, reach)
    paths = [np.asarray(p, dtype=np.float64) for p in lines.values()]
    axis = np.mean([p[-1] for p in paths], axis=0) - np.mean([p[0] for p in paths], axis=0)
    t = V @ (axis / np.linalg.norm(axis))
    end_part = defaults.fibre_area_end_part if end_part is None else end_part
    lo, hi = float(t.min()), float(t.max())
    part = end_part * (hi - lo)
    length = np.array([np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in paths])
    A = None
    areas, rules = [], []
    for k, (cap, on, side) in enumerate(
        ((caps[0], on_origin, t < lo + part), (caps[1], on_insertion, t > hi - part))
    ):
        area = np.zeros(0, dtype=np.int64)
        if on is not None:
            mask = np.asarray(on, dtype=bool)
            if mask.shape != (len(V),):
                raise ValueError(f"a mask per vertex is needed ({len(V)}), got {mask.shape}")
            c = np.flatnonzero(mask & side)
            if len(c):
                A = vertex_adjacency(F, len(V)) if A is None else A
                _, label = connected_components(A[c][:, c], directed=False)
                ends = np.array([p[0] if k == 0 else p[-1] for p in paths])
                # per candidate, its distance to each path's end over that path's length
                d = np.linalg.norm(V[c][:, None, :] - ends[None], axis=2) / length[None]
                near = (d <= end_reach).any(axis=1)
                area = np.sort(c[np.isin(label, np.unique(label[near]))])
        if len(area) >= least:
            areas.append(area)
            rules.append("bones")
        else:
            areas.append(cap)
            rules.append("ends")
    return areas[0], areas[1], (rules[0], rules[1])


@dataclass(frozen=True)
class HarmonicField:
    """A harmonic field between two attachment areas on a regular grid of a muscle's inside.

    Attributes
    ----------
    corner : (3,) float64 array
        The grid's lowest corner; cell ``(i, j, k)`` has its centre at
        ``corner + (i + 1/2, j + 1/2, k + 1/2) * spacing``.
    spacing : float
        The cells' edge (mesh units).
    values : (a, b, c) float64 array
        ``u`` per cell: 0 on the origin's cells, 1 on the insertion's, harmonic between;
        cells outside the domain hold the value of the nearest domain cell.
    domain : (a, b, c) bool array
        The inside cells connected to both attachment areas, where the field was solved.
    """

    corner: FloatArray
    spacing: float
    values: FloatArray
    domain: npt.NDArray[np.bool_]

    def _grid(self, P: FloatArray) -> FloatArray:
        return ((P - self.corner) / self.spacing - 0.5).T

    def sample(self, P: FloatArray) -> FloatArray:
        """(k,) ``u`` at points ``P`` (k, 3), trilinear between cell centres."""
        from scipy import ndimage

        return ndimage.map_coordinates(self.values, self._grid(P), order=1, mode="nearest")

    def direction(self, P: FloatArray) -> FloatArray:
        """(k, 3) unit gradient of ``u`` at ``P``; zero where the gradient vanishes."""
        from scipy import ndimage

        q = self._grid(P)
        g = np.stack(
            [ndimage.map_coordinates(G, q, order=1, mode="nearest") for G in self._gradient],
            axis=1,
        )
        norm = np.linalg.norm(g, axis=1)
        return g / np.where(norm > 0, norm, np.inf)[:, None]

    def in_domain(self, P: FloatArray) -> npt.NDArray[np.bool_]:
        """(k,) whether each point lies in a domain cell."""
        cell = np.floor((P - self.corner) / self.spacing).astype(np.int64)
        shape = np.array(self.domain.shape)
        ok = np.all((cell >= 0) & (cell < shape), axis=1)
        out = np.zeros(len(P), dtype=bool)
        c = cell[ok]
        out[ok] = self.domain[c[:, 0], c[:, 1], c[:, 2]]
        return out

    def climb(self, P: FloatArray, sign: float) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """One step of discrete steepest ascent (``sign`` 1) or descent (-1) of ``u``.

        From the domain cell holding each point to the centre of its face neighbour
        in the domain with the largest ``sign * u``, where that beats the point's own.
        The field is discrete-harmonic off the attachments (each cell the mean of its
        neighbours), so such a neighbour exists everywhere but at an attachment: a
        path of these steps cannot stall in a tendon one cell thin.

        Returns
        -------
        (k, 3) float64 array, (k,) bool array
            The new points, and which points moved.
        """
        shape = np.array(self.domain.shape)
        cell = np.clip(np.floor((P - self.corner) / self.spacing).astype(np.int64), 0, shape - 1)
        best = np.full(len(P), -np.inf)
        target = cell.copy()
        for ax in range(3):
            for step in (-1, 1):
                nb = cell.copy()
                nb[:, ax] += step
                ok = (nb[:, ax] >= 0) & (nb[:, ax] < shape[ax])
                nb_ok = nb[ok]
                val = np.full(len(P), -np.inf)
                inside = self.domain[nb_ok[:, 0], nb_ok[:, 1], nb_ok[:, 2]]
                v = sign * self.values[nb_ok[:, 0], nb_ok[:, 1], nb_ok[:, 2]]
                val[np.flatnonzero(ok)[inside]] = v[inside]
                better = val > best
                best[better] = val[better]
                target[better] = nb[better]
        moved = best > sign * self.sample(P)
        out = P.copy()
        out[moved] = self.corner + (target[moved] + 0.5) * self.spacing
        return out, moved

    def depth(self, P: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Signed distance into the domain at ``P`` (cells; negative outside), and its unit gradient."""
        from scipy import ndimage

        q = self._grid(P)
        sd, *grad = (ndimage.map_coordinates(G, q, order=1, mode="nearest") for G in self._depth)
        g = np.stack(grad, axis=1)
        norm = np.linalg.norm(g, axis=1)
        return sd, g / np.where(norm > 0, norm, np.inf)[:, None]

    @cached_property
    def _depth(self) -> tuple[FloatArray, ...]:
        from scipy import ndimage

        sd = ndimage.distance_transform_edt(self.domain) - ndimage.distance_transform_edt(
            ~self.domain
        )
        return (sd, *np.gradient(sd))

    @cached_property
    def _gradient(self) -> tuple[FloatArray, ...]:
        return tuple(np.gradient(self.values, self.spacing))


def harmonic_field(
    V: npt.ArrayLike,
    F: npt.ArrayLike,
    origin: npt.ArrayLike,
    insertion: npt.ArrayLike,
    *,
    voxels: int = 60_000,
) -> HarmonicField:
    """The harmonic field ``u`` inside a closed mesh, 0 at ``origin`` and 1 at ``insertion``.

    Parameters
    ----------
    V : (n, 3) float64 array
        Vertices of a closed, outward-oriented surface.
    F : (m, 3) int array
        Its triangles.
    origin, insertion : int array_like
        The attachment areas as vertex indices.
    voxels : int, optional
        About how many grid cells lie inside the mesh (the field's resolution).

    Returns
    -------
    HarmonicField

    Raises
    ------
    ValueError
        If an attachment area is empty or the two are not connected through the inside.

    Notes
    -----
    Cells whose centres have a generalized winding number above 1/2 are inside. The
    inside cells within 1.5 cells of an attachment vertex hold its value (Dirichlet);
    the 7-point graph Laplacian of the rest, with no flux to outside cells (Neumann),
    is solved by conjugate gradients with a diagonal preconditioner: a direct solve
    took 6.5 s at 60K cells, this 0.2 s.
    """
    import igl
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import laplacian
    from scipy.sparse.linalg import LinearOperator, cg
    from scipy.spatial import cKDTree

    from ..mesh import volume

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    org = np.unique(np.asarray(origin, dtype=np.int64))
    ins = np.unique(np.asarray(insertion, dtype=np.int64))
    if not len(org) or not len(ins):
        raise ValueError("an attachment area is empty")
    lo, hi = V.min(axis=0), V.max(axis=0)
    h = (abs(float(volume(V, F))) / voxels) ** (1.0 / 3.0)
    shape = np.ceil((hi - lo) / h).astype(int) + 3
    corner = lo - h
    idx = np.indices(shape).reshape(3, -1).T
    centres = corner + (idx + 0.5) * h
    inside = (igl.fast_winding_number(V, F, centres) > 0.5).reshape(shape)

    ins_idx = np.flatnonzero(inside.ravel())
    tree = cKDTree(centres[ins_idx])
    fixed = np.full(inside.size, np.nan)
    for verts, value in ((org, 0.0), (ins, 1.0)):
        near = tree.query_ball_point(V[verts], 1.5 * h)
        cells = np.unique(np.concatenate([np.asarray(c, dtype=np.int64) for c in near]))
        if not len(cells):  # a thin muscle: the nearest inside cell of each vertex
            cells = np.unique(tree.query(V[verts])[1])
        fixed[ins_idx[cells]] = value
    labels, _ = ndimage.label(inside)
    lab = labels.ravel()
    both = np.intersect1d(
        np.unique(lab[np.flatnonzero(fixed == 0.0)]), np.unique(lab[np.flatnonzero(fixed == 1.0)])
    )
    both = both[both > 0]
    if not len(both):
        raise ValueError("the origin and insertion areas are not connected inside the muscle")
    domain = np.isin(lab, both)

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
    return HarmonicField(corner=corner, spacing=float(h), values=U, domain=domain.reshape(shape))


def trace_fibres(field: HarmonicField, seeds: FloatArray) -> list[FloatArray]:
    """Streamlines of ``field`` through ``seeds``, each from ``u`` near 0 to ``u`` near 1.

    Midpoint steps of half a cell along -grad u and +grad u from every seed at once,
    each until ``u`` passes 0.001 (or 0.999) or the next step would leave the
    domain's cells (a thin tendon may hold no cell: the fibre ends on its last one).

    Returns
    -------
    list of (p, 3) float64 arrays
        One poly-line per seed, origin end first; it may stop short of an area.
    """
    h = field.spacing
    limit = int(20 * max(field.values.shape))

    def heading(P: FloatArray, sign: float) -> FloatArray:
        # near a wall (within 1.5 cells) the gradient's interpolation across the grid's
        # staircase may point out of the domain, where the Neumann condition makes the
        # true one tangent to it: the outward part is removed there
        d = sign * field.direction(P)
        sd, inward = field.depth(P)
        near = sd < 1.5
        into = np.minimum(np.sum(d[near] * inward[near], axis=1), 0.0)
        d[near] -= into[:, None] * inward[near]
        return d

    def run(sign: float, stop: float) -> list[FloatArray]:
        P = seeds.copy()
        path = [P.copy()]
        steps = np.zeros(len(P), dtype=int)
        active = np.ones(len(P), dtype=bool)
        step = 0.5 * h
        for _ in range(limit):
            a = np.flatnonzero(active)
            if not len(a):
                break
            d1 = heading(P[a], sign)
            d2 = heading(P[a] + 0.5 * step * d1, sign)
            Q = P[a] + step * d2
            out = ~field.in_domain(Q) | (np.linalg.norm(d2, axis=1) < 1e-6)
            if out.any():
                # a step that still leaves the domain is drawn back to a cell's depth;
                # where that fails too (a passage a cell or two wide), a discrete step
                sd, inward = field.depth(Q[out])
                Q[out] += (h * (1.0 - sd))[:, None] * inward
                out[out] = ~field.in_domain(Q[out])
                if out.any():
                    Q[out], moved = field.climb(P[a[out]], sign)
                    out[np.flatnonzero(out)[moved]] = False
            active[a[out]] = False
            a, Q = a[~out], Q[~out]
            P[a] = Q
            steps[a] += 1
            uu = field.sample(P[a])
            active[a[uu >= stop if sign > 0 else uu <= stop]] = False
            path.append(P.copy())
        T = np.array(path)
        return [T[: steps[j] + 1, j] for j in range(len(P))]

    backs = run(-1.0, 1e-3)
    fwds = run(1.0, 1.0 - 1e-3)
    return [np.concatenate([b[::-1], f[1:]]) for b, f in zip(backs, fwds, strict=True)]


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

    Notes
    -----
    The seeds lie on the level of ``u`` that holds the most grid cells per unit of
    ``u``: the flux is the same through every level, so that is where the muscle is
    widest (the LHDL psoas's half-way level lies in its tendon, and fibres seeded
    there crowd into it). A part of the muscle thinner than about 1.5 grid cells
    holds too few cells for a fibre to pass inside it: a tendon of radius 1.6 cells'
    width passes (tested), one of 0.7 does not. ``voxels`` refines the grid.
    """
    import igl
    from scipy.spatial import cKDTree

    from ..conditions import polyline_at
    from ..coordinates import mean_value_coordinates

    V = np.asarray(muscle.V, dtype=np.float64)
    F = np.asarray(muscle.F, dtype=np.int64)
    if count < 1 or points < 2:
        raise ValueError(f"need count >= 1 and points >= 2, got {count} and {points}")
    if origin is None or insertion is None:
        o, i = attachment_areas(V, lines, reach)
        origin = o if origin is None else origin
        insertion = i if insertion is None else insertion
    field = harmonic_field(V, F, origin, insertion, voxels=voxels)

    # seeds spread (farthest-point sampling) over the level of u that holds the most
    # cells per unit of u: the flux through every level is the same, so that is where
    # the muscle is widest, and the fibres spread over its belly, not its tendon
    cells = np.argwhere(field.domain)
    u = field.values[field.domain]
    counts, edges = np.histogram(u, bins=36, range=(0.05, 0.95))
    level = float(edges[np.argmax(counts)] + 0.5 * (edges[1] - edges[0]))
    k = min(len(u), max(8 * count, 400))
    cand = field.corner + (cells[np.argsort(np.abs(u - level))[:k]] + 0.5) * field.spacing
    rng = np.random.default_rng(seed)
    order = [int(rng.integers(len(cand)))]
    dist = np.linalg.norm(cand - cand[order[0]], axis=1)
    while len(order) < min(len(cand), 2 * count):
        j = int(np.argmax(dist))
        order.append(j)
        dist = np.minimum(dist, np.linalg.norm(cand - cand[j], axis=1))
    whole, seeded = [], []  # the whole fibres, and which of the seeds each came from
    for j, line in enumerate(trace_fibres(field, cand[order])):
        ends = field.sample(line[[0, -1]]) if len(line) >= 3 else np.array([1.0, 0.0])
        if ends[0] <= 0.05 and ends[1] >= 0.95:  # else it stopped short of an attachment
            whole.append(polyline_at(line, np.linspace(0.0, 1.0, points)))
            seeded.append(j)
    inside_all = np.zeros(0, dtype=bool)
    if whole:
        w = igl.fast_winding_number(V, F, np.concatenate(whole))
        inside_all = (w > 0.5).reshape(len(whole), points).all(axis=1)
    if inside_all.sum() < count:
        raise ValueError(
            f"only {int(inside_all.sum())} of {count} fibres stay inside the muscle: "
            "use more voxels"
        )
    kept = np.flatnonzero(inside_all)[:count]
    P = np.array(whole)[kept]
    W = mean_value_coordinates(P.reshape(-1, 3), muscle.cage.C, muscle.cage.CF)
    # each fibre's share of the widest level: its seed's cells there (nearest seed)
    slab = cells[np.abs(u - level) <= 0.5 * (edges[1] - edges[0])]
    centres = field.corner + (slab + 0.5) * field.spacing
    seeds = cand[np.asarray(order)[np.asarray(seeded)[kept]]]
    _, owner = cKDTree(seeds).query(centres)
    share = np.bincount(owner, minlength=len(seeds)).astype(np.float64)
    share /= share.sum()
    lengths = np.linalg.norm(np.diff(P, axis=1), axis=2).sum(axis=1)
    return Fibres(
        points=P,
        W=W,
        origin=np.unique(np.asarray(origin, dtype=np.int64)),
        insertion=np.unique(np.asarray(insertion, dtype=np.int64)),
        spacing=field.spacing,
        share=share,
        area=share * float(muscle.volume_rest) / float(lengths.mean()),
    )


def keep_inside(
    P: npt.ArrayLike, V: npt.ArrayLike, F: npt.ArrayLike, *, depth: float
) -> tuple[FloatArray, int, float, int]:
    """Move the points of ``P`` that lie outside the closed mesh ``(V, F)`` back inside it.

    A deformation carries fibres and surface by the same map, so a fibre leaves its
    muscle only where that map folds the surface onto itself, or where a step that
    moves only the surface (the contact's fine finish) pushes it past the fibre. Such
    a point (winding number below 1: `musclewrap.mesh.winding_numbers`, exact on a
    closed surface and about a tenth of a winding-number hierarchy's cost) goes to its
    closest surface point and
    ``depth`` further in along the surface's inward normal; if that is still not
    inside (a thin part, a fold), 0.3, 3, 0.1, 10, 0.03 or 30 times as far, the
    first that is; failing all, the nearest surface vertex moved ``depth`` inward
    along its normal that is inside.

    Parameters
    ----------
    P : (k, 3) float64 array
        Points, e.g. a frame's fibre points.
    V, F : the deformed surface
    depth : float
        How far inside a moved point goes (mesh units).

    Returns
    -------
    points : (k, 3) float64 array
    moved : int
        How many points were outside.
    farthest : float
        The longest move.
    left : int
        Points still outside (none unless no surface vertex moved inward is inside).
    """
    P = np.array(P, dtype=np.float64)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    out = np.flatnonzero(winding_numbers(P, V, F) < 1)
    if not len(out):
        return P, 0, 0.0, 0
    import igl

    _, _, C, N = igl.signed_distance(
        P[out], V, F, sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL
    )
    start = P[out].copy()
    # candidates along the inward normal from the closest point, in this order: the first
    # inside wins (a thin part may be thinner than the larger depths, a fold deeper)
    depths = depth * np.array([1.0, 0.3, 3.0, 0.1, 10.0, 0.03, 30.0])
    cand = C[None] - depths[:, None, None] * N[None]
    w = winding_numbers(cand.reshape(-1, 3), V, F).reshape(len(depths), -1) >= 1
    first = np.argmax(w, axis=0)
    ok = w[first, np.arange(len(out))]
    P[out] = np.where(ok[:, None], cand[first, np.arange(len(out))], C - depth * N)
    todo = np.flatnonzero(~ok)
    if len(todo):
        # deep in a fold, no point along the normal is inside: the nearest of the surface's
        # vertices moved ``depth`` inward along their normals that is inside
        from scipy.spatial import cKDTree

        Q = V - depth * vertex_normals(V, F)
        Q = Q[winding_numbers(Q, V, F) >= 1]
        if len(Q):
            P[out[todo]] = Q[cKDTree(Q).query(start[todo])[1]]
            todo = todo[:0]
    farthest = float(np.linalg.norm(P[out] - start, axis=1).max())
    return P, len(out), farthest, len(todo)
