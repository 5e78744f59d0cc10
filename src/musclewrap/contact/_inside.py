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

from .._typing import FloatArray, IntArray
from ..mesh import WindingGrid
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
    at least ``8 deep / (1.5 edge)^2``; all of them for ``deep`` = 0).

    Their side is the winding number of the whole surface (exact on a closed
    one); from every vertex found inside, its neighbours on the obstacle are
    tested in turn, until none is inside (a bone enclosed whole is found from
    its rim). The depth is the distance to the triangles around the nearest
    muscle vertex (compiled, `_nearest_face_kernel`): an upper bound; where it
    reaches ``deep``, and for the deepest of all, the distance to the triangles
    around the six nearest muscle vertices and their neighbours (where the
    muscle is thin its nearest vertex can lie on its other side).

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
    grid: WindingGrid | None = None
    out = []
    for b, pl in enumerate(placed):
        m = near.within(b, P, reach)
        ob = pl.obstacle
        rows = ob.vertices_near(pl.to_obstacle(P[m]), 1.5 * edge, sharp)[0] if len(m) else m
        if not len(rows):
            out.append(_none())
            continue
        tested = np.zeros(len(ob.V), dtype=bool)
        tested[rows] = True
        inside_rows = []
        ip, ix = ob.adjacency
        while len(rows):
            if grid is None:
                grid = WindingGrid(P, F)
            hit = grid(pl.to_muscle(ob.V[rows])) > 0
            if not hit.any():
                break
            inside_rows.append(rows[hit])
            # their neighbours on the obstacle, not tested yet (every one: a bone enclosed
            # whole is found from its rim)
            nb = _neighbours(ip, ix, rows[hit])
            nb = np.unique(nb[~tested[nb]])
            tested[nb] = True
            rows = nb
        if not inside_rows:
            out.append(_none())
            continue
        rows = np.concatenate(inside_rows)
        B = np.ascontiguousarray(pl.to_muscle(ob.V[rows]))
        dist, C, fi = _depths(B, m, P, F, adjacency, faces, deep)
        out.append(Inside(rows, B, C, fi, dist))
    return out


def _depths(
    B: FloatArray,
    m: IntArray,
    P: FloatArray,
    F: IntArray,
    adjacency: tuple[IntArray, IntArray],
    faces: tuple[IntArray, IntArray],
    deep: float,
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Distances of the points ``B`` inside the muscle to its surface, closest points, faces.

    First to the triangles around each point's nearest muscle vertex among ``m`` (an
    upper bound: most are chords of a triangle over the bone, a tenth of an edge
    deep), then around its six nearest and their neighbours where the bound reaches
    ``deep``, and for the deepest of all (in order of the bound, until none left can
    beat the best found).
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(P[m])
    start = m[tree.query(B, k=1)[1]].reshape(-1, 1)
    dist = np.empty(len(B))
    C = np.empty((len(B), 3))
    fi = np.empty(len(B), dtype=np.int64)
    _nearest_face_kernel(B, start, P, F, *adjacency, *faces, 0, dist, C, fi)
    k = min(6, len(m))

    def refine(j: IntArray) -> None:
        starts = m[tree.query(B[j], k=k)[1].reshape(len(j), k)]
        _refine(B, j, np.ascontiguousarray(starts), P, F, adjacency, faces, dist, C, fi)

    todo = np.flatnonzero(dist >= deep) if deep > 0 else np.zeros(0, np.int64)
    order = np.argsort(-dist)
    best, i, batch = 0.0, 0, 4
    while i < len(order) and dist[order[i]] > best:
        j = order[i : i + batch]
        refine(j)
        best = max(best, float(dist[j].max()))
        i, batch = i + batch, 2 * batch
    todo = np.setdiff1d(todo, order[:i])
    if len(todo):
        refine(todo)
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


def _neighbours(ip: IntArray, ix: IntArray, rows: IntArray) -> IntArray:
    """The CSR neighbours of ``rows`` (with repeats)."""
    if not len(rows):
        return np.zeros(0, np.int64)
    return np.concatenate([ix[ip[r] : ip[r + 1]] for r in rows])


@numba.njit(cache=True)
def _nearest_face_kernel(B, starts, P, F, Ap, Ai, VFp, VFi, ring, dist, C, face):  # noqa: ANN001, ANN202 # pragma: no cover
    # per point: the closest point on the faces around each of its start vertices (and,
    # with ring 1, their neighbours'): unsigned, the side is the winding number's
    for i in range(B.shape[0]):
        p = B[i]
        best = np.inf
        bf = -1
        b0 = b1 = b2 = 0.0
        for s in range(starts.shape[1]):
            v0 = starts[i, s]
            for k in range(Ap[v0] if ring else Ap[v0 + 1], Ap[v0 + 1] + 1):
                u = v0 if k == Ap[v0 + 1] else Ai[k]
                for m in range(VFp[u], VFp[u + 1]):
                    f = VFi[m]
                    q, _, _, _ = _closest_on_triangle(p, P[F[f, 0]], P[F[f, 1]], P[F[f, 2]])
                    d0, d1, d2 = p[0] - q[0], p[1] - q[1], p[2] - q[2]
                    d = d0 * d0 + d1 * d1 + d2 * d2
                    if d < best:
                        best, bf = d, f
                        b0, b1, b2 = q[0], q[1], q[2]
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
    pts = []
    for L in lines:
        L = np.asarray(L, dtype=np.float64)
        for a, b in zip(L[:-1], L[1:], strict=True):
            k = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing)))
            pts.append(a + np.linspace(0.0, 1.0, k + 1)[:, None] * (b - a))
    if not pts or not placed:
        return 0.0
    Q = np.vstack(pts)
    return max(pl.obstacle.measure(pl.to_obstacle(Q))[1] for pl in placed)


@numba.njit(cache=True)
def _closest_on_triangle(p, a, b, c):  # noqa: ANN001, ANN202 # pragma: no cover
    # Ericson, Real-Time Collision Detection 5.1.5: the closest point and its barycentrics
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0.0 and d2 <= 0.0:
        return a, 1.0, 0.0, 0.0
    bp = p - b
    d3, d4 = ab @ bp, ac @ bp
    if d3 >= 0.0 and d4 <= d3:
        return b, 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return a + t * ab, 1.0 - t, t, 0.0
    cp = p - c
    d5, d6 = ab @ cp, ac @ cp
    if d6 >= 0.0 and d5 <= d6:
        return c, 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return a + t * ac, 1.0 - t, 0.0, t
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return b + t * (c - b), 0.0, 1.0 - t, t
    den = 1.0 / (va + vb + vc)
    v, w = vb * den, vc * den
    return a + v * ab + w * ac, 1.0 - v - w, v, w
