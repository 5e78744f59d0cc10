"""Obstacle vertices inside a muscle: where a bone stands in it between the muscle's vertices.

Keeping every muscle vertex out of a bone does not keep the bone out of the muscle: a
ridge sharper than the muscle's triangles (a crest, a spur, a spike of the
segmentation) can stand between vertices that all lie outside it, and a muscle that
went round a bone on the wrong side encloses it whole. This finds the obstacle's
vertices inside the muscle's surface as it is: exactly, by winding numbers
(`musclewrap.mesh.winding_numbers`), among those near the muscle's vertices that come
near the obstacle, and from each one found inside through its neighbours on the
obstacle, so that a whole enclosed patch is found from its rim.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

from .._typing import FloatArray, IntArray
from ..constants import defaults
from ..mesh import WindingGrid, invert_rigid
from ._near import Near
from ._placed import Placed

__all__ = ["Inside", "bone_vertices_inside", "line_inside_depth"]


@dataclass(frozen=True)
class Inside:
    """One obstacle's vertices inside a muscle.

    Attributes
    ----------
    rows : (k,) int64 array
        The obstacle's vertices (rows of ``Obstacle.V``).
    B : (k, 3) float64 array
        Their positions in the muscle's frame.
    C : (k, 3) float64 array
        Their closest points on the muscle's surface.
    face : (k,) int64 array
        The muscle's triangles that hold ``C``.
    depth : (k,) float64 array
        Their distance to the muscle's surface.
    """

    rows: IntArray
    B: FloatArray
    C: FloatArray
    face: IntArray
    depth: FloatArray

    @property
    def deepest(self) -> float:
        """The largest depth (0 when none is inside)."""
        return float(self.depth.max(initial=0.0))


def bone_vertices_inside(
    P: FloatArray,
    F: IntArray,
    placed: Sequence[Placed],
    near: Near,
    *,
    edge: float,
    adjacency: tuple[IntArray, IntArray],
    faces: tuple[IntArray, IntArray],
    reach: float | None = None,
    deep: float = 0.0,
) -> list[Inside]:
    """Per obstacle, its vertices inside the closed muscle surface ``P, F``.

    The candidates are the obstacle's vertices within 1.5 ``edge`` of a muscle
    vertex that may lie within ``reach`` (default 0.6 ``edge``) of the
    obstacle's margin (``near``'s bounds): a bone that stands in the muscle
    crosses its surface there, where the muscle's vertices around it lie no
    further from it than a triangle's vertices from a point inside it (about
    ``edge / sqrt(3)``); of those, the ones convex enough to stand ``deep`` out
    of a muscle triangle whose vertices lie on the bone (`Obstacle.convexity`
    at least ``8 deep / (1.5 edge)^2``; all of them for ``deep`` = 0). Round a
    muscle vertex whose triangles are larger than that assumes by
    ``defaults.contact_bone_stretch`` in area (stretched at a pose past anatomy),
    the bone vertices within 1.5 ``edge`` are held to its own triangles' sag
    instead (``2 deep / r^2``, ``r`` the largest radius of their smallest
    enclosing circles). And every obstacle vertex with an edge longer than 1.5
    ``edge`` (a model's coarse bone) within that edge and 1.5 ``edge`` of such a
    muscle vertex, whatever its convexity (`_coarse_near`).

    Their side is the winding number of the whole surface (exact on a closed
    one); from every vertex found inside, its neighbours on the obstacle are
    tested in turn, until none is inside (a bone enclosed whole is found from
    its rim). The depth is the distance to the triangles around the nearest
    muscle vertex (compiled, `_nearest_face_kernel`): an upper bound, exact
    for nearly all; where it reaches ``deep``, the distance to the triangles
    around the six nearest muscle vertices and their neighbours (where the
    muscle is thin its nearest vertex can lie on its other side). So a depth
    is exact from ``deep`` on, and below it at most the bound.

    Parameters
    ----------
    P : (n, 3) float64 array
        The muscle's vertices (in its frame).
    F : (m, 3) int64 array
        Its triangles (closed, outward).
    placed : sequence of Placed
    near : Near
        Lower bounds of the muscle vertices' distances to each obstacle.
    edge : float
        The muscle's mean edge length.
    adjacency : (indptr, indices)
        The muscle's vertex adjacency (CSR).
    faces : (indptr, indices)
        The muscle's `vertex_faces`.
    reach : float, optional
    deep : float, optional
        The depth that matters (a push): deeper ones get the closer look.

    Returns
    -------
    list of Inside
        One per obstacle, in order.
    """
    reach = 0.6 * edge if reach is None else reach
    P = np.ascontiguousarray(P, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    # where a bone stands in the muscle between its vertices, it is convex enough to
    # stand out of a muscle triangle by ``deep`` (the sag e^2 / 8 R of a triangle's
    # edges e of up to 1.5 mean edges over a radius R)
    sharp = 8.0 * deep / (1.5 * edge) ** 2 if deep > 0 else -np.inf
    # per obstacle its candidates first: the muscle's grid is then binned once round them
    # all (and a few cells beyond, where the flood goes), not once per flood step
    cands: list[tuple[IntArray, IntArray, IntArray] | None] = []
    for b, pl in enumerate(placed):
        near_b = near.within(b, P, reach)
        Q = pl.to_obstacle(P[near_b])
        # near's bounds are from where the vertices were (they may have moved since): of
        # those, the ones the grid's bounds here still allow within reach look for the
        # candidates; the depths start from the nearest of them all
        keep = pl.obstacle.bounds(Q)[0] < near.allowed[b][near_b] + reach
        if not keep.any():
            cands.append(None)
            continue
        kept = np.flatnonzero(keep)
        rows, which = pl.obstacle.vertices_near(Q[kept], 1.5 * edge, sharp)
        if sharp > 0:
            # where the triangles round a muscle vertex are much larger than the sag above
            # assumes (stretched at a pose past anatomy), a flatter bone stands as deep
            # between their vertices: the bone vertices near it held to its own triangles' sag
            need = 2.0 * deep / _reach_sq(P, F, faces, near_b[kept])
            wide = np.flatnonzero(need < sharp / defaults.contact_bone_stretch)
            if len(wide):
                more, at = pl.obstacle.vertices_near(Q[kept[wide]], 1.5 * edge)
                at = wide[at]
                new = pl.obstacle.convexity[more] > need[at]
                rows, first = np.unique(np.concatenate([rows, more[new]]), return_index=True)
                which = np.concatenate([which, at[new]])[first]
        more, at = _coarse_near(pl, Q[kept], 1.5 * edge)
        if len(more):
            rows, first = np.unique(np.concatenate([rows, more]), return_index=True)
            which = np.concatenate([which, at])[first]
        cands.append((near_b, rows, kept[which]) if len(rows) else None)
    grid: WindingGrid | None = None
    if any(c is not None for c in cands):
        grid = WindingGrid(P, F, lazy=True)
        grid.bin_around(
            np.vstack(
                [pl.to_muscle(pl.obstacle.V[c[1]]) for pl, c in zip(placed, cands, strict=True)
                 if c is not None]
            ),
            margin=2,
        )  # fmt: skip
    out = []
    for pl, c in zip(placed, cands, strict=True):
        if c is None:
            out.append(_none())
            continue
        assert grid is not None
        m, rows, which = c
        ob = pl.obstacle
        # each candidate's nearest muscle vertex (among m): where its depth is looked for
        nearest = np.full(len(ob.V), -1, dtype=np.int64)
        nearest[rows] = m[which]
        # the candidates, then the neighbours on the obstacle of those inside (every one: a
        # bone enclosed whole is found from its rim)
        rows = grid.flood(ob.V, ob.adjacency, rows, None if pl.T is None else invert_rigid(pl.T))
        if not len(rows):
            out.append(_none())
            continue
        B = np.ascontiguousarray(pl.to_muscle(ob.V[rows]))
        dist, C, fi = _depths(B, nearest[rows], m, P, F, adjacency, faces, deep)
        out.append(Inside(rows, B, C, fi, dist))
    return out


def _coarse_near(pl: Placed, Q: FloatArray, reach: float) -> tuple[IntArray, IntArray]:
    """The obstacle's vertices with an edge longer than ``reach`` that may stand in the muscle.

    Where the obstacle's triangles are larger than the muscle's (a model's bone of a
    few hundred vertices), a vertex of its inside the muscle lies no further from a
    muscle vertex ``Q`` near the obstacle than its longest edge and ``reach``: each of
    its edges to a vertex outside crosses the muscle's surface, whose vertices lie
    round the crossing on the obstacle. Its curvature toward its neighbours says
    nothing there (a corner between large flat triangles stands out of a muscle
    triangle however flat it is over the obstacle's edges): every such vertex within
    that distance, and its nearest point of ``Q`` (an index into it).
    """
    ob = pl.obstacle
    longest = ob.longest_edges
    coarse = np.flatnonzero(longest > reach)
    none = np.zeros(0, dtype=np.int64)
    if not len(coarse) or not len(Q):
        return none, none
    radius = longest[coarse] + reach
    X = ob.V[coarse]
    lo, hi = Q.min(axis=0), Q.max(axis=0)
    box = np.all((X >= lo - radius[:, None]) & (X <= hi + radius[:, None]), axis=1)
    if not box.any():
        return none, none
    coarse, radius, X = coarse[box], radius[box], X[box]
    d, j = cKDTree(Q).query(X, distance_upper_bound=float(radius.max()))
    ok = d <= radius
    return coarse[ok].astype(np.int64), j[ok].astype(np.int64)


def _reach_sq(
    P: FloatArray, F: IntArray, faces: tuple[IntArray, IntArray], m: IntArray
) -> FloatArray:
    """Per muscle vertex ``m``, the largest squared radius of its triangles' smallest circles.

    The circumscribed circle of an acute triangle, half the longest edge of another: a
    point over the triangle lies within that radius of its centre, and a bone of radius
    ``R`` under it rises at most ``r^2 / 2 R`` above its vertices' plane (compiled).
    """
    out = np.empty(len(m))
    _reach_kernel(P, F, faces[0], faces[1], np.ascontiguousarray(m, dtype=np.int64), out)
    return out


@numba.njit(cache=True)
def _reach_kernel(P, F, VFp, VFi, m, out):  # noqa: ANN001, ANN202 # pragma: no cover
    # per vertex: the largest squared radius over its triangles of the smallest circle
    # round each (the circumscribed one of an acute triangle, half the longest edge else)
    for i in range(m.shape[0]):
        v = m[i]
        best = 1e-300
        for p in range(VFp[v], VFp[v + 1]):
            f = VFi[p]
            a, b, c = F[f, 0], F[f, 1], F[f, 2]
            e0 = e1 = e2 = 0.0
            for k in range(3):
                u = P[b, k] - P[c, k]
                w = P[c, k] - P[a, k]
                z = P[a, k] - P[b, k]
                e0 += u * u
                e1 += w * w
                e2 += z * z
            ux, uy, uz = P[b, 0] - P[a, 0], P[b, 1] - P[a, 1], P[b, 2] - P[a, 2]
            wx, wy, wz = P[c, 0] - P[a, 0], P[c, 1] - P[a, 1], P[c, 2] - P[a, 2]
            cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
            area2 = cx * cx + cy * cy + cz * cz  # (2 area)^2
            longest = max(e0, max(e1, e2))
            if 2.0 * longest >= e0 + e1 + e2 or not area2 > 0.0:
                r2 = 0.25 * longest
            else:
                r2 = e0 * e1 * e2 / (4.0 * area2)
            best = max(best, r2)
        out[i] = best


def _depths(
    B: FloatArray,
    start: IntArray,
    m: IntArray,
    P: FloatArray,
    F: IntArray,
    adjacency: tuple[IntArray, IntArray],
    faces: tuple[IntArray, IntArray],
    deep: float,
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Distances of the points ``B`` inside the muscle to its surface, closest points, faces.

    First to the triangles around each point's nearest muscle vertex ``start``
    (-1: unknown, then the nearest among ``m``): an upper bound, and most are chords
    of a triangle over the bone, under a tenth of an edge deep; where the bound
    reaches ``deep``, the distance to the triangles around the six nearest
    vertices among ``m`` and their neighbours.
    """
    tree = None  # of the vertices m, built once where needed
    if (start < 0).any():
        tree = cKDTree(P[m])
        lost = start < 0
        start = start.copy()
        start[lost] = m[tree.query(B[lost], k=1)[1]]
    dist = np.empty(len(B))
    C = np.empty((len(B), 3))
    fi = np.empty(len(B), dtype=np.int64)
    _nearest_face_kernel(B, start.reshape(-1, 1), P, F, *adjacency, *faces, 0, dist, C, fi)
    j = np.flatnonzero(dist >= deep)
    if len(j):
        k = min(6, len(m))
        tree = cKDTree(P[m]) if tree is None else tree
        starts = m[tree.query(B[j], k=k)[1].reshape(len(j), k)]
        _refine(B, j, np.ascontiguousarray(starts), P, F, adjacency, faces, dist, C, fi)
    return dist, C, fi


def _refine(
    B: FloatArray,
    rows: IntArray,
    starts: IntArray,
    P: FloatArray,
    F: IntArray,
    adjacency: tuple[IntArray, IntArray],
    faces: tuple[IntArray, IntArray],
    dist: FloatArray,
    C: FloatArray,
    fi: IntArray,
) -> None:
    """The closest point of ``B[rows]`` around each of ``starts`` (a row each), in place."""
    Q = np.ascontiguousarray(B[rows])
    d = np.empty(len(rows))
    Cj = np.empty((len(rows), 3))
    fj = np.empty(len(rows), dtype=np.int64)
    _nearest_face_kernel(Q, np.ascontiguousarray(starts), P, F, *adjacency, *faces, 1, d, Cj, fj)
    better = d < dist[rows]
    r = rows[better]
    dist[r], C[r], fi[r] = d[better], Cj[better], fj[better]


@numba.njit(cache=True)
def _nearest_face_kernel(B, starts, P, F, Ap, Ai, VFp, VFi, ring, dist, C, face):  # noqa: ANN001, ANN202 # pragma: no cover
    # per point: the closest point on the faces around each of its start vertices (and,
    # with ring 1, their neighbours'): unsigned, the side is the winding number's
    for i in range(B.shape[0]):
        p0, p1, p2 = B[i, 0], B[i, 1], B[i, 2]
        best = np.inf
        bf = -1
        b0 = b1 = b2 = 0.0
        for s in range(starts.shape[1]):
            v0 = starts[i, s]
            for k in range(Ap[v0] if ring else Ap[v0 + 1], Ap[v0 + 1] + 1):
                u = v0 if k == Ap[v0 + 1] else Ai[k]
                for m in range(VFp[u], VFp[u + 1]):
                    f = VFi[m]
                    d, q0, q1, q2 = _closest_on_triangle(p0, p1, p2, P, F[f])
                    if d < best:
                        best, bf = d, f
                        b0, b1, b2 = q0, q1, q2
        dist[i] = np.sqrt(best)
        C[i, 0], C[i, 1], C[i, 2] = b0, b1, b2
        face[i] = bf


def _none() -> Inside:
    return Inside(
        np.zeros(0, np.int64),
        np.zeros((0, 3)),
        np.zeros((0, 3)),
        np.zeros(0, np.int64),
        np.zeros(0),
    )


def line_inside_depth(
    lines: Sequence[FloatArray], placed: Sequence[Placed], spacing: float
) -> float:
    """How deep the poly-lines ``lines`` (muscle frame) run inside the obstacles (0: not).

    Each segment is sampled every ``spacing`` or less and the samples measured
    exactly (`Obstacle.measure`): where a model's action line itself runs
    through a bone, the muscle cannot follow it there.
    """
    pts = [_segment_samples(np.asarray(L, dtype=np.float64), spacing) for L in lines]
    pts = [q for q in pts if len(q)]
    if not pts or not placed:
        return 0.0
    Q = np.vstack(pts)
    return max(pl.obstacle.measure(pl.to_obstacle(Q))[1] for pl in placed)


def _segment_samples(L: FloatArray, spacing: float) -> FloatArray:
    """Each segment of the poly-line ``L`` sampled at ``k + 1`` even steps.

    ``k`` the least that keeps them ``spacing`` or less apart: ``a + np.linspace(0, 1, k +
    1) (b - a)`` segment by segment, to the bit (its steps ``j (1 / k)``, the last 1),
    without a call a segment.
    """
    if len(L) < 2:
        return np.zeros((0, 3))
    a, d = L[:-1], L[1:] - L[:-1]
    r = np.linalg.norm(d, axis=1) / spacing
    # a segment's own norm (a dot product) may differ from the rows' in the last bit: where
    # that could move the ceiling, the segment's own
    tie = np.flatnonzero(np.abs(r - np.rint(r)) <= 1e-9 * np.maximum(r, 1.0))
    r[tie] = [np.linalg.norm(d[i]) / spacing for i in tie]
    k = np.maximum(1, np.ceil(r).astype(np.int64))
    seg = np.repeat(np.arange(len(k)), k + 1)
    start = np.concatenate([[0], np.cumsum(k + 1)[:-1]])
    j = (np.arange(len(seg)) - start[seg]).astype(np.float64)
    t = j * (1.0 / k[seg])
    t[start + k] = 1.0
    return a[seg] + t[:, None] * d[seg]


@numba.njit(cache=True)
def _closest_on_triangle(p0, p1, p2, V, t):  # noqa: ANN001, ANN202 # pragma: no cover
    # the squared distance of p to triangle t (a row of F) of V, and the closest point
    x, y, z = t[0], t[1], t[2]
    wu, wv, ww = _triangle_weights(
        p0, p1, p2, V[x, 0], V[x, 1], V[x, 2], V[y, 0], V[y, 1], V[y, 2],
        V[z, 0], V[z, 1], V[z, 2],
    )  # fmt: skip
    q0 = wu * V[x, 0] + wv * V[y, 0] + ww * V[z, 0]
    q1 = wu * V[x, 1] + wv * V[y, 1] + ww * V[z, 1]
    q2 = wu * V[x, 2] + wv * V[y, 2] + ww * V[z, 2]
    return (p0 - q0) ** 2 + (p1 - q1) ** 2 + (p2 - q2) ** 2, q0, q1, q2


@numba.njit(cache=True, error_model="numpy")
def _triangle_weights(p0, p1, p2, a0, a1, a2, b0, b1, b2, c0, c1, c2):  # noqa: ANN001, ANN202 # pragma: no cover
    # Ericson, Real-Time Collision Detection 5.1.5, in scalars (no array per call): the
    # barycentric weights (u, v, w) of the point of triangle abc closest to p. A triangle
    # of no area gives NaN (numpy's division, not an exception): its distance compares
    # false with every other, so it is never taken as the closest
    ab0, ab1, ab2 = b0 - a0, b1 - a1, b2 - a2
    ac0, ac1, ac2 = c0 - a0, c1 - a1, c2 - a2
    ap0, ap1, ap2 = p0 - a0, p1 - a1, p2 - a2
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0
    bp0, bp1, bp2 = p0 - b0, p1 - b1, p2 - b2
    d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
    d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return 1.0 - t, t, 0.0
    cp0, cp1, cp2 = p0 - c0, p1 - c1, p2 - c2
    d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
    d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return 1.0 - t, 0.0, t
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 0.0, 1.0 - t, t
    den = 1.0 / (va + vb + vc)
    v, w = vb * den, vc * den
    return 1.0 - v - w, v, w
