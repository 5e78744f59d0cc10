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

import numpy as np

from .._typing import FloatArray, IntArray
from ..mesh import winding_numbers
from ._near import Near
from ._placed import Placed

__all__ = ["Inside", "bone_inside_depth", "bone_vertices_inside", "line_inside_depth"]


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
) -> list[Inside]:
    """Per obstacle, its vertices inside the closed muscle surface ``P, F`` (exact).

    The candidates are the obstacle's vertices within 1.5 ``edge`` of a muscle
    vertex that may lie within ``reach`` (default 1.5 ``edge``) of the
    obstacle's margin (``near``'s bounds): a bone that stands in the muscle
    crosses its surface there. Their side is the winding number of the whole
    surface (exact on a closed one); from every vertex found inside, its
    neighbours on the obstacle are tested in turn, until none is inside. The
    depth and the nearest triangle come from the triangles around the six
    nearest of those muscle vertices and their neighbours (compiled,
    `_local_side_kernel`).

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

    Returns
    -------
    list of Inside
        One per obstacle, in order.
    """
    from scipy.spatial import cKDTree

    from ._finish import _local_side_kernel

    reach = 1.5 * edge if reach is None else reach
    P = np.ascontiguousarray(P, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    out = []
    for b, pl in enumerate(placed):
        m = near.within(b, P, reach)
        if not len(m):
            out.append(_none())
            continue
        ob = pl.obstacle
        cand, start = ob.vertices_near(pl.to_obstacle(P[m]), 1.5 * edge)
        if not len(cand):
            out.append(_none())
            continue
        start = m[start]
        tested = np.zeros(len(ob.V), dtype=bool)
        tested[cand] = True
        inside_rows = []
        rows, starts = cand, start
        Vb = ob.V
        ip, ix = ob.adjacency
        while len(rows):
            B = pl.to_muscle(Vb[rows])
            w = winding_numbers(B, P, F)
            hit = w > 0
            if not hit.any():
                break
            inside_rows.append(rows[hit])
            # their neighbours on the obstacle, not tested yet, start where they did
            nb, src = _neighbours(ip, ix, rows[hit], starts[hit])
            fresh = ~tested[nb]
            nb, src = nb[fresh], src[fresh]
            nb, first = np.unique(nb, return_index=True)
            src = src[first]
            tested[nb] = True
            rows, starts = nb, src
        if not inside_rows:
            out.append(_none())
            continue
        rows = np.concatenate(inside_rows)
        B = np.ascontiguousarray(pl.to_muscle(Vb[rows]))
        # the closest point on the triangles around each of its nearest muscle vertices
        # (among those near the obstacle; several: where the muscle is thin, the nearest
        # vertex can lie on its other side)
        k = min(6, len(m))
        near_k = cKDTree(P[m]).query(B, k=k)[1].reshape(len(B), k)
        dist = np.full(len(B), np.inf)
        C = np.empty((len(B), 3))
        fi = np.empty(len(B), dtype=np.int64)
        phi = np.empty(len(B))
        Cj = np.empty((len(B), 3))
        fj = np.empty(len(B), dtype=np.int64)
        for j in range(k):
            _local_side_kernel(B, m[near_k[:, j]], P, F, *adjacency, *faces, phi, Cj, fj)
            better = np.abs(phi) < dist
            dist[better], C[better], fi[better] = np.abs(phi[better]), Cj[better], fj[better]
        out.append(Inside(rows, B, C, fi, dist))
    return out


def _neighbours(
    ip: IntArray, ix: IntArray, rows: IntArray, starts: IntArray
) -> tuple[IntArray, IntArray]:
    """The CSR neighbours of ``rows``, each with the start of the row it came from."""
    counts = ip[rows + 1] - ip[rows]
    if not counts.sum():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    idx = np.concatenate([ix[ip[r] : ip[r + 1]] for r in rows])
    return idx, np.repeat(starts, counts)


def _none() -> Inside:
    return Inside(
        np.zeros(0, np.int64),
        np.zeros((0, 3)),
        np.zeros((0, 3)),
        np.zeros(0, np.int64),
        np.zeros(0),
    )


def bone_inside_depth(
    P: FloatArray,
    F: IntArray,
    placed: Sequence[Placed],
    *,
    edge: float,
    adjacency: tuple[IntArray, IntArray],
    faces: tuple[IntArray, IntArray],
) -> tuple[int, float]:
    """How many obstacle vertices lie inside the muscle, and the deepest one's depth.

    `bone_vertices_inside` on a pose deformed without contact (the run measures
    what the bones it does not keep the muscle out of do).
    """
    if not placed:
        return 0, 0.0
    found = bone_vertices_inside(
        P, F, placed, Near(P, placed, 0.0), edge=edge, adjacency=adjacency, faces=faces
    )
    return sum(len(f.rows) for f in found), max(f.deepest for f in found)


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
