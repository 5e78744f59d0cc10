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
``reach`` of ``a``'s surface at rest with ``a`` in front of them, or inside it
(`facing_faces`): muscles slide along each other, they do not go round. Measured on
the gait2392 walk's worst frames (`python benchmarks/tuning/bench_thresholds.py --only
facing`): the faces within 10, 15, 25 or 1,000 mm leave no vertex more than 0.03 mm
inside another, within 5 mm 0.75 mm (too few faces: the sartorius creases, 0.65).
Without the sides, 5-15 mm left 0.07 mm and 25 mm or more 1.1-1.3 mm: the far side of a
thin muscle within reach.

Each vertex inside another muscle comes with the point of the other's surface it
leaves through (`Overlap.point`, `Overlap.face`): the solver takes each side's share
there (`musclewrap.solver.meet`), whatever order the muscles come in.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba
import numpy as np
from scipy.spatial import cKDTree

from .._typing import FloatArray, IntArray
from ..constants import defaults, tol
from ..mesh import (
    WindingGrid,
    barycentric,
    bin_boxes,
    face_normals,
    in_oriented_box,
    mean_edge_length,
    oriented_box,
    vertex_adjacency,
    volume,
)
from ._finish import longest_pushes, nudge, press, triangle_pushes
from ._inside import _closest_on_triangle

__all__ = [
    "Meeting",
    "Overlap",
    "RestPair",
    "apart_at_rest",
    "distance_outside",
    "every_pair",
    "facing_faces",
    "facing_pairs",
    "meetings",
    "overlap_depths",
    "overlaps",
    "push_apart",
]


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


def _closest(
    P: FloatArray, V: FloatArray, F: IntArray, *, grid: bool = False
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Distances of the points ``P`` to the triangles ``F`` of ``V``, closest points, their rows of F.

    Exact either way: where there are few points, per point the triangles whose bounding
    spheres come within the best so far, looked for in rings of a uniform grid of their
    centroids round the point (one pass over the triangles to bin them, no tree); else
    libigl's AABB tree (about 0.4 us per triangle to build, per call: the surface moves
    every round). On capsules the grid is 5-23 times quicker than the tree up to 1,000
    points (`python benchmarks/speed/bench_closest.py`). ``grid``: the grid whatever the
    count (points near the surface, where its rings stay few).
    """
    P = np.ascontiguousarray(P, dtype=np.float64)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    if grid or len(P) <= defaults.closest_grid_points:
        dist, C = np.empty(len(P)), np.empty((len(P), 3))
        face = np.empty(len(P), dtype=np.int64)
        _closest_kernel(P, V, F, dist, C, face)
        return dist, C, face
    import igl

    sq, face, C = igl.point_mesh_squared_distance(P, V, F)
    return np.sqrt(np.maximum(sq, 0.0)), np.asarray(C), np.asarray(face, dtype=np.int64)


def distance_outside(P: FloatArray, V: FloatArray, F: IntArray) -> FloatArray:
    """Each point's distance outside the closed surface ``V, F`` (0 inside it).

    Inside by the exact winding number (`WindingGrid`, binned only where the points
    are), the distance by exact closest points (`_closest`): a few hundred points
    against a muscle of 50,000 faces in a third of the time libigl's trees took
    (built per call), the same distances to 1e-13.
    """
    P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(P))
    if not len(P):
        return out
    far = np.flatnonzero(WindingGrid(V, F, lazy=True)(P) <= 0)
    if len(far):
        out[far] = _closest(P[far], V, F)[0]
    return out


@numba.njit(cache=True, error_model="numpy")
def _closest_kernel(P, V, F, dist, C, face):  # noqa: ANN001, ANN202 # pragma: no cover
    # per point, the least distance over the triangles, ties to the lowest row of F. The
    # triangles' bounding spheres (about their centroids) are binned by centroid in a
    # uniform grid of cells about a triangle wide; each point looks in rings of cells
    # round its own, a triangle whose sphere lies further than the best so far skipped,
    # until a ring's nearest centroid, less the largest radius, lies beyond the best. The
    # same distance, point and row as every triangle's (the tests compare them with the
    # loop over all of them); numpy's division: a triangle of no area gives NaN, never
    # taken, where a loop that reached it first would have raised
    # (element loops for the centroids' box, the radii's mean and the wide ones: numpy's
    # reductions and np.flatnonzero compiled here took 0.7 s of a first run, the same
    # values for a surface of finite positions)
    m = F.shape[0]
    cen = np.empty((m, 3))
    rad = np.empty(m)
    lo = np.empty(3)  # the centroids' box
    hi = np.empty(3)
    total = 0.0
    for f in range(m):
        r = 0.0
        for k in range(3):
            c = (V[F[f, 0], k] + V[F[f, 1], k] + V[F[f, 2], k]) / 3.0
            cen[f, k] = c
            if f == 0 or c < lo[k]:
                lo[k] = c
            if f == 0 or c > hi[k]:
                hi[k] = c
        for j in range(3):
            e = 0.0
            for k in range(3):
                e += (V[F[f, j], k] - cen[f, k]) ** 2
            r = max(r, e)
        rad[f] = np.sqrt(r)
        total += rad[f]
    ext = np.empty(3)
    for k in range(3):
        ext[k] = hi[k] - lo[k]
    h = max(2.0 * (total / m), 1e-12 * max(ext[0], ext[1], ext[2]), 1e-300)
    dims = np.empty(3, dtype=np.int64)
    while True:  # cells about a triangle wide, at most 8 a triangle
        for k in range(3):
            dims[k] = int(ext[k] / h) + 1
        if dims[0] * dims[1] * dims[2] <= 8 * m + 8:
            break
        h *= 1.5
    # triangles wider than two cells (four times the mean) are looked at for every point
    # (a few slivers would otherwise hold the rings open); the rest bound how far the
    # rings go, two rings more at most
    wide = np.empty(m, dtype=np.int64)
    n_wide = 0
    big = 0.0
    boxes = np.empty((m, 6), dtype=np.int64)  # each in its centroid's cell, the wide in none
    for f in range(m):
        if rad[f] > 2.0 * h:
            boxes[f, 0] = 1
            for k in range(1, 6):
                boxes[f, k] = 0
            wide[n_wide] = f
            n_wide += 1
            continue
        big = max(big, rad[f])
        for k in range(3):
            c = min(dims[k] - 1, int((cen[f, k] - lo[k]) / h))
            boxes[f, 2 * k] = boxes[f, 2 * k + 1] = c
    wide = wide[:n_wide]
    start, items = bin_boxes(boxes, dims[0], dims[1], dims[2])
    ring_max = max(dims[0], dims[1], dims[2])
    at = np.empty(3, dtype=np.int64)
    for i in range(P.shape[0]):
        p0, p1, p2 = P[i, 0], P[i, 1], P[i, 2]
        for k in range(3):
            at[k] = min(dims[k] - 1, max(0, int(max(P[i, k] - lo[k], 0.0) / h)))
        best, bf = np.inf, -1
        b0 = b1 = b2 = 0.0
        for f in wide:
            d, q0, q1, q2 = _closest_on_triangle(p0, p1, p2, V, F[f])
            if d < best or (d == best and f < bf):
                best, bf = d, f
                b0, b1, b2 = q0, q1, q2
        for ring in range(ring_max + 1):
            # every centroid in this ring lies at least (ring - 1) h from the point
            if ring >= 2 and bf >= 0:
                gap = (ring - 1) * h - big
                if gap > 0.0 and gap * gap > best * (1.0 + 1e-9):
                    break
            for a0 in range(max(0, at[0] - ring), min(dims[0] - 1, at[0] + ring) + 1):
                for a1 in range(max(0, at[1] - ring), min(dims[1] - 1, at[1] + ring) + 1):
                    shell = abs(a0 - at[0]) == ring or abs(a1 - at[1]) == ring
                    step = 1 if shell or ring == 0 else 2 * ring  # else its two ends only
                    for a2 in range(at[2] - ring, at[2] + ring + 1, step):
                        if a2 < 0 or a2 >= dims[2]:
                            continue
                        c = (a0 * dims[1] + a1) * dims[2] + a2
                        for q in range(start[c], start[c + 1]):
                            f = items[q]
                            dc = np.sqrt(
                                (p0 - cen[f, 0]) ** 2 + (p1 - cen[f, 1]) ** 2
                                + (p2 - cen[f, 2]) ** 2
                            )  # fmt: skip
                            lb = dc - rad[f]
                            if lb > 0.0 and lb * lb > best:
                                continue
                            d, q0, q1, q2 = _closest_on_triangle(p0, p1, p2, V, F[f])
                            if d < best or (d == best and f < bf):
                                best, bf = d, f
                                b0, b1, b2 = q0, q1, q2
        dist[i] = np.sqrt(best)
        C[i, 0], C[i, 1], C[i, 2] = b0, b1, b2
        face[i] = bf


class _Facer:
    """What finding the faces of other muscles that face one muscle ``V, F`` needs, once.

    Its vertices' tree (`scipy.spatial.cKDTree`), the radius round a vertex that covers
    its triangles (every point of a triangle lies within its circumradius, acute, or half
    its longest edge, obtuse, of a corner: within the longest edge over sqrt 3 either
    way) and its `WindingGrid` (made when first needed, where none is given).
    """

    def __init__(self, V: FloatArray, F: IntArray, grid: WindingGrid | None = None) -> None:
        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        # the box along its principal axes (the surface lies in it: a point more than the
        # reach outside it is more than the reach from the surface)
        self.box = oriented_box(self.V)
        self.tree = cKDTree(self.V[np.unique(self.F)])
        E = self.V[self.F] - self.V[np.roll(self.F, 1, axis=1)]
        # widened by a billionth: a bound, whatever the rounding
        self.cover = float(np.sqrt((E * E).sum(axis=2).max())) / np.sqrt(3.0) * (1.0 + 1e-9)
        self._grid = grid

    @property
    def grid(self) -> WindingGrid:
        if self._grid is None:
            self._grid = WindingGrid(self.V, self.F)
        return self._grid

    def faces(
        self, centroids: FloatArray, reach: float, normals: FloatArray | None = None
    ) -> IntArray:
        """The rows of ``centroids`` within ``reach`` of the surface or inside it (exact).

        ``normals`` (the faces' outward normals, any length): of those outside the
        surface, only the faces it lies in front of (its closest point to the centroid
        not behind the face's plane).
        """
        R, lo, hi = self.box
        cand = in_oriented_box(centroids, R, lo - reach, hi + reach)
        if not len(cand):
            return cand.astype(np.int64)
        Q = centroids[cand]
        # the distance to the nearest vertex (infinite beyond reach + cover) is at least
        # the distance to the surface, and at most cover more
        upper = self.tree.query(Q, k=1, distance_upper_bound=reach + self.cover)[0]
        near = upper <= reach
        # those the bounds leave unsure (a band round the reach), and with normals every
        # one within reach, take their exact closest points (the 18 VHF muscles' 306
        # pairs at rest, 506,000 points: 6.9 s all by the compiled grid, 6.0 s all by
        # libigl's tree, 5.5 s as `_closest` chooses by their count)
        unsure = upper - self.cover <= reach
        exact = np.flatnonzero(unsure if normals is not None else unsure & ~near)
        if len(exact):
            dist, C = _closest(Q[exact], self.V, self.F, grid=normals is None)[:2]
            near[exact] = dist <= reach
            if normals is not None:
                # a face the surface lies behind faces away from it: taking a vertex
                # out through it passes one muscle through the other (the far wall of
                # a thin muscle round this one), unless the face lies inside this surface
                near[exact] &= ((C - Q[exact]) * normals[cand[exact]]).sum(axis=1) >= 0.0
        inside = np.zeros(len(cand), dtype=bool)
        rest = np.flatnonzero(~near)
        if len(rest):
            inside[rest] = self.grid(Q[rest]) > 0
        return np.ascontiguousarray(cand[inside | near], dtype=np.int64)


def facing_faces(
    Va: FloatArray,
    Fa: IntArray,
    Vb: FloatArray,
    Fb: IntArray,
    reach: float,
    grid: WindingGrid | None = None,
) -> IntArray:
    """The faces of ``b`` that face ``a``: their centroids within ``reach`` of ``a`` or inside it.

    Computed at rest, with both surfaces in one frame. Empty when none is. ``grid``:
    ``a``'s `WindingGrid`, where the caller has it. A face outside ``a`` faces it only
    where ``a`` lies in front of it (its near point not behind the face's plane): where
    ``b`` is thinner than ``reach`` (a sleeve round ``a``, a flat muscle on it) its far
    wall lies within reach too, and a vertex of ``a`` taken out through that wall passes
    through ``b`` (three sleeves nested round a rod and pressed 4-6 mm: the outer one ran
    away by 6-10 mm with hundreds of vertices inside the middle one, and the rounds hit
    their cap; with the near side only, 2-3 rounds and none inside).

    Exact, and mostly without closest points: a centroid's distance to ``a``'s nearest
    vertex bounds its distance to the surface from above, and less the radius round a
    vertex that covers ``a``'s triangles from below (`_Facer`). Only the centroids whose
    two bounds straddle ``reach``, and with the sides those within it, take the exact
    closest point, and only those not within reach take the winding number (each centroid
    taken to the surface, and a tree over the surface per pair, cost the 18 VHF muscles
    13 s for all 306 pairs at rest; 3.0 s so without the sides, 5.5 s with them:
    `python benchmarks/speed/bench_closest.py --facing`). Where the nearest vertex decided
    the side instead of the closest point, where it lies in front, the LHDL walk took 506
    rounds again, not 425, most 8 a frame, not 3.
    """
    return _Facer(Va, Fa, grid).faces(Vb[Fb].mean(axis=1), reach, face_normals(Vb, Fb))


def overlaps(
    surfaces: Mapping[str, tuple[FloatArray, IntArray]],
    pairs: Sequence[tuple[str, str]],
    facing: Mapping[tuple[str, str], IntArray],
    memo: dict[Any, Any] | None = None,
) -> dict[str, list[Overlap]]:
    """Per muscle, its vertices inside each muscle it meets, with their way out.

    ``surfaces`` (name -> ``V, F``) are the muscles in one frame, in one frame of
    reference; ``pairs`` those that may meet (sorted names); ``facing[a, b]``
    the faces of ``b`` that face ``a`` (`facing_faces`; where a pair has none, all
    of ``b``'s). Each muscle's list is in the order of the others' names; a
    muscle's result depends on the surfaces alone, not on their order. ``memo``: a
    dict kept by a caller whose surfaces do not all move between calls (rounds):
    each surface's box and `WindingGrid` and each pair's result are kept with the
    position arrays they came from, and taken again while the same arrays come back.
    """
    memo = {} if memo is None else memo
    # by name: each surface's box and grid, with the positions they came from (string keys:
    # a pair's result is kept under the tuple of its names)
    kept_boxes = memo.setdefault("boxes", {})
    kept_grids = memo.setdefault("grids", {})
    boxes = {}
    for n, (V, _) in surfaces.items():
        kept = kept_boxes.get(n)
        if kept is None or kept[0] is not V:
            # along its principal axes: an oblique muscle fills little of its axis-aligned
            # box, where another's vertices that cannot be inside it would be tested
            kept = kept_boxes[n] = (V, *oriented_box(V))
        boxes[n] = kept[1:]
    out: dict[str, list[Overlap]] = {n: [] for n in surfaces}
    todo = []  # (me, other, its points in the other's box) of the pairs looked at anew
    for a, b in sorted(pairs):
        for me, other in ((a, b), (b, a)):
            P = surfaces[me][0]
            kept = memo.get((me, other))
            if kept is not None and kept[0] is P and kept[1] is surfaces[other][0]:
                if kept[2] is not None:  # neither has moved since
                    out[me].append(kept[2])
                continue
            todo.append((me, other, in_oriented_box(P, *boxes[other])))
    # one grid per surface looked into (kept while it does not move), binned once round
    # every point that looks into it
    grids: dict[str, WindingGrid] = {}
    for other in sorted({o for _, o, cand in todo if len(cand)}):
        kept = kept_grids.get(other)
        if kept is None or kept[0] is not surfaces[other][0]:
            kept = kept_grids[other] = (
                surfaces[other][0],
                WindingGrid(*surfaces[other], lazy=True),
            )
        grids[other] = kept[1]
        grids[other].bin_around(
            np.vstack([surfaces[me][0][cand] for me, o, cand in todo if o == other])
        )
    for me, other, cand in todo:
        P, (Vo, Fo) = surfaces[me][0], surfaces[other]
        found = None
        if len(cand):
            found = _inside_other(P, cand, Vo, Fo, grids[other], facing, (me, other))
        memo[me, other] = (P, Vo, found)
        if found is not None:
            out[me].append(found)
    for n in out:
        out[n].sort(key=lambda o: o.other)
    return out


def _inside_other(
    P: FloatArray,
    cand: IntArray,
    Vo: FloatArray,
    Fo: IntArray,
    grid: WindingGrid,
    facing: Mapping[tuple[str, str], IntArray],
    pair: tuple[str, str],
) -> Overlap | None:
    """The points ``P[cand]`` of ``pair[0]`` inside the surface ``Vo, Fo`` of ``pair[1]``, their way out.

    ``grid``: the other surface's `WindingGrid`. ``facing[pair]`` is looked up only
    where some point is inside (`facing_pairs` finds a pair's faces when first
    looked up).
    """
    rows = cand[grid(P[cand]) > 0]
    if not len(rows):
        return None
    f = facing.get(pair)
    every = f is None or not len(f)
    depth, C, which = _closest(P[rows], Vo, Fo if every else Fo[f])
    d = (C - P[rows]) / np.maximum(depth, 1e-300)[:, None]
    return Overlap(pair[1], rows, depth, d, which if every else f[which], C)


def overlap_depths(
    surfaces: Mapping[str, tuple[FloatArray, IntArray]],
    pairs: Sequence[tuple[str, str]],
    memo: Mapping[Any, Any] | None = None,
) -> dict[str, tuple[int, float]]:
    """Per muscle, how many of its vertices lie inside another muscle and the deepest one's depth.

    Exact: winding numbers of the whole surfaces and the distance to the whole
    surface of the one it is in (not only the faces that face it). Muscles in no
    pair: (0, 0). ``memo``: an `overlaps` memo of these rounds: what it holds for
    surfaces that have not moved since (the same arrays) is taken again, the boxes,
    the grids and the pairs with no vertex inside the other (the same, whichever
    faces the way out takes); a pair with vertices inside is looked at anew.
    """
    seed: dict[Any, Any] = {}
    if memo is not None:
        seed = {k: v for k, v in memo.items() if not isinstance(k, tuple) or v[2] is None}
        seed = {k: dict(v) if isinstance(v, dict) else v for k, v in seed.items()}
    out = {n: (0, 0.0) for n in surfaces}
    for n, found in overlaps(surfaces, pairs, {}, seed).items():
        if found:
            out[n] = (
                sum(len(o.rows) for o in found),
                max(float(o.depth.max()) for o in found),
            )
    return out


def facing_pairs(
    meshes: Mapping[str, tuple[FloatArray, IntArray]],
    reach: float | None = None,
    cache: Path | None = None,
) -> Mapping[tuple[str, str], IntArray]:
    """`facing_faces` for every ordered pair of ``meshes`` (at rest, in one frame).

    Each pair's faces are found when first looked up, and kept: most pairs of a
    scene's muscles never overlap, and finding them all is most of the cost of a
    large scene (18 muscles: 306 ordered pairs, 5.5 s; 13 s before `_Facer`). ``reach``
    (mesh units): default ``defaults.muscle_facing_reach``. ``cache``: a folder where
    each pair's faces are kept between processes and runs (keyed by both meshes as
    placed and the reach).
    """
    reach = defaults.muscle_facing_reach if reach is None else reach
    return _FacingOnDemand(meshes, reach, cache)


class _FacingOnDemand(Mapping[tuple[str, str], IntArray]):
    """`facing_pairs`: each pair's facing faces found when first asked for."""

    def __init__(
        self,
        meshes: Mapping[str, tuple[FloatArray, IntArray]],
        reach: float,
        cache: Path | None = None,
    ) -> None:
        self.meshes, self.reach, self.cache = meshes, reach, cache
        self.found: dict[tuple[str, str], IntArray] = {}
        # per muscle, what finding the faces that face it needs, and its faces' centroids
        self.facers: dict[str, _Facer] = {}
        self.centroids: dict[str, tuple[FloatArray, FloatArray]] = {}  # and normals
        self.digests: dict[str, str] = {}  # of each mesh as placed (the cache's keys)

    def __getitem__(self, pair: tuple[str, str]) -> IntArray:
        if pair not in self.found:
            a, b = pair
            if a == b or a not in self.meshes or b not in self.meshes:
                raise KeyError(pair)
            if self.cache is None:
                self.found[pair] = self._find(a, b)
            else:
                from .._cache import cached_measure

                # keyed by both meshes as placed (each hashed once, not once per pair)
                parts = [self._digest(a), self._digest(b), repr(self.reach)]
                got = cached_measure(
                    self.cache, "facing-2", parts, lambda: {"faces": self._find(a, b)}
                )
                self.found[pair] = np.ascontiguousarray(got["faces"], dtype=np.int64)
        return self.found[pair]

    def _digest(self, n: str) -> str:
        if n not in self.digests:
            from .._cache import digest

            V, F = self.meshes[n]
            self.digests[n] = digest(
                np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64)
            )
        return self.digests[n]

    def _find(self, a: str, b: str) -> IntArray:
        if a not in self.facers:
            self.facers[a] = _Facer(*self.meshes[a])
        if b not in self.centroids:
            Vb, Fb = self.meshes[b]
            self.centroids[b] = (Vb[Fb].mean(axis=1), face_normals(Vb, Fb))
        centroids, normals = self.centroids[b]
        return self.facers[a].faces(centroids, self.reach, normals)

    def __iter__(self) -> Iterator[tuple[str, str]]:
        names = sorted(self.meshes)
        return ((a, b) for a in names for b in names if a != b)

    def __len__(self) -> int:
        return len(self.meshes) * (len(self.meshes) - 1)


def every_pair(
    names: Sequence[str], pairs: Sequence[tuple[str, str]] | None = None
) -> list[tuple[str, str]]:
    """The pairs of ``names`` that may meet, each in name order, sorted.

    Every pair (``pairs`` None), or those of ``pairs`` whose muscles are both in
    ``names`` (the scene's ``[collisions] pairs``).
    """
    if pairs is None:
        names = sorted(names)
        return [(a, b) for i, a in enumerate(names) for b in names[i + 1 :]]
    return sorted({(min(p), max(p)) for p in pairs if p[0] in names and p[1] in names})


def _cat(found: Sequence[Overlap], field: str, shape: tuple[int, ...]) -> Any:
    """One field of several overlaps, end to end (empty of ``shape`` where there are none)."""
    if not found:
        return np.zeros(shape, dtype=np.int64 if field in ("rows", "face") else np.float64)
    return np.concatenate([getattr(o, field) for o in found])


@dataclass(frozen=True)
class Meeting:
    """One muscle's side of its overlaps with the others in one round, each taking its share.

    Attributes
    ----------
    rows, need, out
        Its vertices inside other muscles, how far each goes out, along which unit
        direction.
    faces, at, give, back
        Where another muscle's vertex stands inside it: its triangles, the points on
        them that give way, how far, along which unit direction (into this muscle).
    depth, given : float
        Its deepest vertex inside another; the deepest of another's inside it.
    """

    rows: IntArray
    need: FloatArray
    out: FloatArray
    faces: IntArray
    at: FloatArray
    give: FloatArray
    back: FloatArray
    depth: float
    given: float

    def rotated(self, T: FloatArray | None) -> Meeting:
        """The directions taken from the common frame into the muscle's (``T``: muscle to common)."""
        if T is None:
            return self
        R = T[:3, :3]
        return dataclasses.replace(self, out=self.out @ R, back=self.back @ R)


def meetings(found: Mapping[str, Sequence[Overlap]], share: float) -> dict[str, Meeting]:
    """Every muscle's side of the overlaps ``found`` (`overlaps`), split ``share`` to ``1 - share``.

    A vertex inside another muscle goes out by ``share`` of its depth; the other's
    surface gives way by the rest where the vertex stands (so the two surfaces meet
    between where they were, whichever muscle is named first).
    """
    given: dict[str, list[Overlap]] = {n: [] for n in found}
    for m in sorted(found):
        for o in found[m]:
            given[o.other].append(o)
    return {
        n: Meeting(
            _cat(found[n], "rows", (0,)),
            share * _cat(found[n], "depth", (0,)),
            _cat(found[n], "out", (0, 3)),
            _cat(given[n], "face", (0,)),
            _cat(given[n], "point", (0, 3)),
            (1.0 - share) * _cat(given[n], "depth", (0,)),
            -_cat(given[n], "out", (0, 3)),
            max((float(o.depth.max()) for o in found[n]), default=0.0),
            max((float(o.depth.max()) for o in given[n]), default=0.0),
        )
        for n in found
    }


def push_apart(
    V: FloatArray,
    F: IntArray,
    A: Any,
    m: Meeting,
    S: FloatArray,
    *,
    volume_target: float,
    edge: float,
    shape_rest: FloatArray | None = None,
    umbrella: Any = None,
    plate: bool = False,
) -> FloatArray | None:
    """A muscle's fine vertices out of the others, its surface giving way, volume exact.

    ``m`` (in the muscle's frame: `Meeting.rotated`) moves each of its vertices
    inside another by ``need`` along ``out`` and the corners of each triangle that
    carries another's vertex by the least push that moves the point ``at`` by
    ``give`` along ``back`` (`triangle_pushes`; ``S``: the muscle's positions in the
    frame of ``at``), each a slack of ``tol.contact`` edges further; a vertex pushed
    twice takes the longer push. `nudge` spreads them over the rings round them and
    restores the volume; with ``plate``, `press` moves them as a thin plate instead
    (``shape_rest``, ``umbrella``: its bound and Laplacian). ``A``: the vertex
    adjacency. None where nothing moves or the volume cannot be restored.
    """
    slack = tol.contact * edge
    verts = np.concatenate([m.rows, F[m.faces].ravel()])
    if not len(verts):
        return None
    disp = np.vstack(
        [
            (m.need + slack)[:, None] * m.out,
            triangle_pushes(m.at, S[F[m.faces]], (m.give + slack)[:, None] * m.back),
        ]
    )
    if plate:
        T = F[m.faces]
        w = np.clip(barycentric(m.at, S[T]), 0.0, None)
        w = w / w.sum(axis=1)[:, None]
        one = np.zeros((len(m.rows), 3))
        one[:, 0] = 1.0
        return press(
            V, F, A,
            np.vstack([np.repeat(m.rows[:, None], 3, axis=1), T]),
            np.vstack([one, w]),
            np.vstack([m.out, m.back]),
            np.concatenate([m.need, m.give]) + slack,
            volume_target=volume_target, edge=edge, shape_rest=shape_rest,
            umbrella=umbrella,
        )  # fmt: skip
    push, size = np.zeros((len(V), 3)), np.zeros(len(V))
    longest_pushes(push, size, verts, disp)
    hit = np.unique(verts)
    return nudge(V, F, A, hit, push[hit], volume_target=volume_target, edge=edge)


@dataclass(frozen=True)
class RestPair:
    """Two muscles that overlapped at rest, and how far.

    ``inside``: how many vertices of each lay inside the other; ``depth``: the
    deepest of each (mesh units); ``moved``: how far each muscle's vertices were
    moved at most by the resolution (0 where it was not resolved); ``left``: the
    deepest vertex of either still inside the other after it (exact).
    """

    pair: tuple[str, str]
    inside: tuple[int, int]
    depth: tuple[float, float]
    moved: tuple[float, float] = (0.0, 0.0)
    left: float = 0.0


def apart_at_rest(
    meshes: Mapping[str, tuple[FloatArray, IntArray]],
    pairs: Sequence[tuple[str, str]] | None = None,
    facing: Mapping[tuple[str, str], IntArray] | None = None,
    *,
    resolve: bool = True,
) -> tuple[dict[str, FloatArray], list[RestPair], int]:
    """Segmented muscles that overlap at rest taken apart once: both sides, volumes exact.

    Jacobi rounds on the fine vertices, as the last of each frame's rounds
    (`musclewrap.solver.meet`): every vertex inside another muscle goes out by half
    its depth and the other's surface gives way by the other half
    (`push_apart`, by `nudge`'s spread: the frames' thin plate, ``muscle_fine_plate``,
    is not taken here, so the rest state, and the fibres laid in it, does not hang on
    it), until no vertex is deeper than ``defaults.muscle_overlap_depth``
    of its mean edges (at most ``defaults.muscle_rest_rounds`` rounds). ``meshes``
    (name -> ``V, F``, one frame), ``pairs`` (default every pair), ``facing``
    (`facing_pairs`, made here when None). ``resolve=False`` measures only.

    Returns
    -------
    V : dict of name to (n, 3) array
        The positions (the given arrays where a muscle did not move).
    overlapped : list of RestPair
        Each pair that overlapped, in the order of the names.
    rounds : int
        The rounds taken.
    """
    names = sorted(meshes)
    pairs = every_pair(names, pairs)
    V = {n: np.asarray(meshes[n][0], dtype=np.float64) for n in names}
    facing = facing_pairs({n: (V[n], meshes[n][1]) for n in names}) if facing is None else facing
    F = {n: meshes[n][1] for n in names}
    surf = {n: (V[n], F[n]) for n in names}
    memo: dict[Any, Any] = {}
    found = overlaps(surf, pairs, facing, memo)
    first = {(n, o.other): o for n in names for o in found[n]}
    rounds = 0
    if resolve and first:
        edge = {n: mean_edge_length(V[n], F[n]) for n in names}
        target = {n: volume(V[n], F[n]) for n in names}
        adjacency: dict[str, Any] = {}
        for _ in range(defaults.muscle_rest_rounds):
            meet = meetings(found, defaults.muscle_share)
            if max(max(m.depth, m.given) / edge[n] for n, m in meet.items()) <= (
                defaults.muscle_overlap_depth
            ):
                break
            for n, m in meet.items():
                if max(m.depth, m.given) / edge[n] <= defaults.muscle_overlap_depth:
                    continue
                if n not in adjacency:
                    adjacency[n] = vertex_adjacency(F[n], len(V[n]))
                P = push_apart(
                    V[n], F[n], adjacency[n], m, V[n], volume_target=target[n], edge=edge[n]
                )
                if P is not None:
                    V[n] = P
            rounds += 1
            surf = {n: (V[n], F[n]) for n in names}
            found = overlaps(surf, pairs, facing, memo)
    # exact: winding numbers and distances to the whole surfaces
    after = {
        (n, o.other): float(o.depth.max()) for n, f in overlaps(surf, pairs, {}).items() for o in f
    }
    rest = []
    for a, b in pairs:
        oa, ob = first.get((a, b)), first.get((b, a))
        if oa is None and ob is None:
            continue
        moved = tuple(
            float(np.linalg.norm(V[n] - np.asarray(meshes[n][0]), axis=1).max()) for n in (a, b)
        )
        rest.append(
            RestPair(
                (a, b),
                (0 if oa is None else len(oa.rows), 0 if ob is None else len(ob.rows)),
                (0.0 if oa is None else float(oa.depth.max()),
                 0.0 if ob is None else float(ob.depth.max())),
                moved if resolve else (0.0, 0.0),
                max(after.get((a, b), 0.0), after.get((b, a), 0.0)),
            )
        )  # fmt: skip
    return V, rest, rounds
