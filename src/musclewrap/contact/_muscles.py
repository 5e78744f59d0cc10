"""Muscles as obstacles of each other: which pairs meet, where each one faces the other, overlaps.

A bone is rigid and gets a signed-distance grid once; a muscle changes shape every
frame, so against a muscle the contact works on its surface as it is: which of
another muscle's vertices lie inside it (exact winding numbers, `WindingGrid`) and
the way out of it.

Which way out is a matter of sides, as with bones (`SideReference`): a vertex that
has gone deeper into its neighbour than half the neighbour's thickness is nearer
the far side, and taking it out there passes one muscle through the other. Two
muscles meet where they face each other at rest: the way out of muscle ``b`` for a
vertex of muscle ``a`` is the nearest point on the faces of ``b`` that lie within
``reach`` of ``a``'s surface at rest, or inside it (`facing_faces`): muscles slide
along each other, they do not go round. Measured on the gait2392 walk's worst frames
(BENCHMARKS.md): the nearest way over all faces sends rectus femoris through vastus
lateralis (25 mm); the faces within 15-25 mm at rest resolve every frame; within
5-10 mm too few faces face each other and the ways out run 70-130 mm.

The depth a vertex is taken out by is half its depth, the other half taken by the
neighbour's vertices inside it: the two surfaces meet between where they were
(`overlaps`), whatever order the muscles come in.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ..mesh import WindingGrid
from ._inside import _triangle_weights

__all__ = ["Overlap", "contact_pairs", "facing_faces", "overlap_depths", "overlaps"]


@dataclass(frozen=True)
class Overlap:
    """One muscle's vertices inside another muscle, and their way out of it.

    Attributes
    ----------
    other : str
        The muscle they are inside.
    rows : (k,) int64 array
        The vertices (rows of this muscle's ``V``).
    depth : (k,) float64 array
        Their distance to the other muscle's faces that face this one (at least
        their distance to its whole surface).
    out : (k, 3) float64 array
        Unit directions from each vertex to its nearest point on those faces.
    face : (k,) int64 array
        The other muscle's triangles (rows of its ``F``) that hold those points.
    point : (k, 3) float64 array
        The points (where the other muscle's surface must give way).
    """

    other: str
    rows: IntArray
    depth: FloatArray
    out: FloatArray
    face: IntArray
    point: FloatArray


def _closest(P: FloatArray, V: FloatArray, F: IntArray) -> tuple[FloatArray, FloatArray, IntArray]:
    """Distances of the points ``P`` to the triangles ``F`` of ``V``, closest points, their rows of F.

    Exact either way: every triangle per point where that is few tests (a few points
    inside a neighbour: 0.2 ms where building libigl's tree costs 1.2 ms), else
    libigl's AABB tree.
    """
    P = np.ascontiguousarray(P, dtype=np.float64)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    if len(P) * len(F) <= 200_000:
        dist, C = np.empty(len(P)), np.empty((len(P), 3))
        face = np.empty(len(P), dtype=np.int64)
        _closest_kernel(P, V, F, dist, C, face)
        return dist, C, face
    import igl

    sq, face, C = igl.point_mesh_squared_distance(P, V, F)
    return np.sqrt(np.maximum(sq, 0.0)), np.asarray(C), np.asarray(face, dtype=np.int64)


@numba.njit(cache=True)
def _closest_kernel(P, V, F, dist, C, face):  # noqa: ANN001, ANN202 # pragma: no cover
    # every triangle for every point (Ericson's closest point, `_triangle_weights`)
    for i in range(P.shape[0]):
        p0, p1, p2 = P[i, 0], P[i, 1], P[i, 2]
        best = np.inf
        b0 = b1 = b2 = 0.0
        bf = -1
        for f in range(F.shape[0]):
            x, y, z = F[f, 0], F[f, 1], F[f, 2]
            wu, wv, ww = _triangle_weights(
                p0, p1, p2, V[x, 0], V[x, 1], V[x, 2], V[y, 0], V[y, 1], V[y, 2],
                V[z, 0], V[z, 1], V[z, 2],
            )  # fmt: skip
            q0 = wu * V[x, 0] + wv * V[y, 0] + ww * V[z, 0]
            q1 = wu * V[x, 1] + wv * V[y, 1] + ww * V[z, 1]
            q2 = wu * V[x, 2] + wv * V[y, 2] + ww * V[z, 2]
            d = (p0 - q0) ** 2 + (p1 - q1) ** 2 + (p2 - q2) ** 2
            if d < best:
                best = d
                bf = f
                b0, b1, b2 = q0, q1, q2
        dist[i] = np.sqrt(best)
        C[i, 0], C[i, 1], C[i, 2] = b0, b1, b2
        face[i] = bf


def contact_pairs(
    surfaces: Mapping[str, tuple[FloatArray, IntArray]], reach: Mapping[str, float]
) -> list[tuple[str, str]]:
    """The pairs of muscles whose surfaces come within ``reach`` of each other (sorted names).

    ``reach[name]`` is each muscle's own distance (a few of its mean edge lengths);
    a pair meets where its surfaces come within the larger of the two: a vertex
    of either within it of the other's surface, or inside it.
    """
    names = sorted(surfaces)
    out = []
    for i, a in enumerate(names):
        Va, Fa = surfaces[a]
        for b in names[i + 1 :]:
            Vb, Fb = surfaces[b]
            r = max(reach[a], reach[b])
            if (Va.min(0) - r > Vb.max(0)).any() or (Vb.min(0) - r > Va.max(0)).any():
                continue
            if _within(Va, Vb, Fb, r) or _within(Vb, Va, Fa, r):
                out.append((a, b))
    return out


def _within(P: FloatArray, V: FloatArray, F: IntArray, r: float) -> bool:
    """Whether a point of ``P`` lies within ``r`` of the closed surface ``V, F`` or inside it."""
    lo, hi = V.min(0) - r, V.max(0) + r
    P = P[((P >= lo) & (P <= hi)).all(axis=1)]
    if not len(P):
        return False
    if (WindingGrid(V, F)(P) > 0).any():
        return True
    return bool(_closest(P, V, F)[0].min() <= r)


def facing_faces(
    Va: FloatArray, Fa: IntArray, Vb: FloatArray, Fb: IntArray, reach: float
) -> IntArray:
    """The faces of ``b`` that face ``a``: their centroids within ``reach`` of ``a`` or inside it.

    Computed at rest, with both surfaces in one frame. Empty when none is.
    """
    cen = Vb[Fb].mean(axis=1)
    lo, hi = Va.min(0) - reach, Va.max(0) + reach
    cand = np.flatnonzero(((cen >= lo) & (cen <= hi)).all(axis=1))
    if not len(cand):
        return cand.astype(np.int64)
    inside = WindingGrid(Va, Fa)(cen[cand]) > 0
    near = _closest(cen[cand], Va, Fa)[0] <= reach
    return np.ascontiguousarray(cand[inside | near], dtype=np.int64)


def overlaps(
    surfaces: Mapping[str, tuple[FloatArray, IntArray]],
    pairs: Sequence[tuple[str, str]],
    facing: Mapping[tuple[str, str], IntArray],
) -> dict[str, list[Overlap]]:
    """Per muscle, its vertices inside each muscle it meets, with their way out.

    ``surfaces`` (name -> ``V, F``) are the muscles in one frame, in one frame of
    reference; ``pairs`` (`contact_pairs`) those that may meet; ``facing[a, b]``
    the faces of ``b`` that face ``a`` (`facing_faces`; where a pair has none, all
    of ``b``'s). Each muscle's list is in the order of the others' names; a
    muscle's result depends on the surfaces alone, not on their order.
    """
    grids: dict[str, WindingGrid] = {}
    boxes = {n: (V.min(0), V.max(0)) for n, (V, _) in surfaces.items()}
    out: dict[str, list[Overlap]] = {n: [] for n in surfaces}
    for a, b in sorted(pairs):
        for me, other in ((a, b), (b, a)):
            P = surfaces[me][0]
            Vo, Fo = surfaces[other]
            lo, hi = boxes[other]
            cand = np.flatnonzero(((P >= lo) & (P <= hi)).all(axis=1))
            if not len(cand):
                continue
            if other not in grids:
                grids[other] = WindingGrid(Vo, Fo)
            rows = cand[grids[other](P[cand]) > 0]
            if not len(rows):
                continue
            f = facing.get((me, other))
            every = f is None or not len(f)
            depth, C, which = _closest(P[rows], Vo, Fo if every else Fo[f])
            d = (C - P[rows]) / np.maximum(depth, 1e-300)[:, None]
            out[me].append(Overlap(other, rows, depth, d, which if every else f[which], C))
    for n in out:
        out[n].sort(key=lambda o: o.other)
    return out


def overlap_depths(
    surfaces: Mapping[str, tuple[FloatArray, IntArray]], pairs: Sequence[tuple[str, str]]
) -> dict[str, tuple[int, float]]:
    """Per muscle, how many of its vertices lie inside another muscle and the deepest one's depth.

    Exact: winding numbers of the whole surfaces and the distance to the whole
    surface of the one it is in (not only the faces that face it). Muscles in no
    pair: (0, 0).
    """
    out = {n: (0, 0.0) for n in surfaces}
    for n, found in overlaps(surfaces, pairs, {}).items():
        if found:
            out[n] = (
                sum(len(o.rows) for o in found),
                max(float(o.depth.max()) for o in found),
            )
    return out
