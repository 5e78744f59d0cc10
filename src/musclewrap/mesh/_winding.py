"""Exact winding numbers of points about a closed triangle surface, by signed ray crossings.

For a closed, consistently oriented surface the winding number of a point is an
integer: the signed count of the surface's crossings by any ray from the point
(+1 where the ray leaves through a face, -1 where it enters one). Here the ray runs
along +x. Each face is tested in the yz plane with edge functions that are computed
once per edge from the edge's lower-numbered end (so the two faces of an edge get the
same number, bit for bit) and with ties broken by a symbolic shift of the point
(Edelsbrunner & Muecke's simulation of simplicity): the test is watertight, and a ray
through an edge or a vertex is counted exactly once. A uniform grid over the yz
plane, built per call, keeps the faces tested per point to a few.

This is the inside test for many points against a surface that changes every frame:
it costs about one pass over the faces plus a few faces per point, where a
winding-number hierarchy (libigl's ``FastWindingNumberBVH``) costs 10 ms to build
over a muscle's surface before its first query.
"""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

__all__ = ["WindingGrid", "bin_boxes", "winding_numbers"]


def winding_numbers(P: npt.ArrayLike, V: npt.ArrayLike, F: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Winding number of every point of ``P`` about the closed surface ``(V, F)``.

    Exact (an integer) for a closed, consistently oriented triangle surface, also
    where it intersects itself (then a point may lie inside twice, or -1 times); 1
    inside and 0 outside a clean outward-oriented surface. A point on the surface
    itself gets either value of the two sides. On a surface with holes the count
    depends on the ray's direction: use generalized winding numbers there.

    Parameters
    ----------
    P : (k, 3) float array
        Query points.
    V : (n, 3) float array
    F : (m, 3) int array
        The surface.

    Returns
    -------
    (k,) int64 array
    """
    P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
    if not len(P):
        return np.zeros(0, dtype=np.int64)
    return WindingGrid(V, F)(P)


class WindingGrid:
    """`winding_numbers` about one surface, for several batches of points.

    The surface's faces are binned over the yz plane (one pass over the faces);
    each call then tests a few faces per point.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        The surface (closed, consistently oriented).
    lazy : bool, optional
        Bin no face at construction; a query whose points lie outside the cells
        binned so far bins the box of cells round them and the cells binned before
        (`bin_around` does so beforehand, for several batches at once). The cells are
        those of the whole grid, each with the same faces in the same order, so the
        winding numbers are the same bit for bit; a few points near a large surface
        then cost a pass over its vertices and faces, not the binning of every face
        (about 6 cells a face).
    """

    def __init__(self, V: npt.ArrayLike, F: npt.ArrayLike, *, lazy: bool = False) -> None:
        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        g = max(1, int(np.sqrt(len(self.F) / 2.0)))
        self._g = g
        self._cells = _cells_kernel(self.V, g) if len(self.F) else None
        self._region = (0, -1, 0, -1)  # cells binned: i0, i1, j0, j1 (none)
        self._bins = (np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64))
        if self._cells is not None and not lazy:
            self._bin((0, g - 1, 0, g - 1))

    def bin_around(self, P: npt.ArrayLike, margin: int = 0) -> None:
        """Bin the box of cells that queries of the points ``P`` (k, 3) need, if not binned.

        ``margin``: that many cells more on every side (where later queries will go).
        """
        P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
        if not len(P) or self._cells is None:
            return
        y0, z0, hy, hz = self._cells[:4]
        need = _region_kernel(P, self._g, y0, z0, hy, hz)
        if margin:
            g = self._g
            need = (
                max(need[0] - margin, 0),
                min(need[1] + margin, g - 1),
                max(need[2] - margin, 0),
                min(need[3] + margin, g - 1),
            )
        i0, i1, j0, j1 = self._region
        if need[0] >= i0 and need[1] <= i1 and need[2] >= j0 and need[3] <= j1:
            return
        if i0 <= i1:
            # the cells binned so far too: a grid asked near one place, then near another
            # and back (a flood over a bone's vertices, a muscle's rounds), bins once a
            # place, not once a call (each binning is a pass over every face)
            need = (min(need[0], i0), max(need[1], i1), min(need[2], j0), max(need[3], j1))
        self._bin(need)

    def _bin(self, region: tuple[int, int, int, int]) -> None:
        assert self._cells is not None
        self._bins = _bin_kernel(self.F, *self._cells[4:], *region)
        self._region = region

    def __call__(self, P: npt.ArrayLike) -> npt.NDArray[np.int64]:
        """Winding numbers of the points ``P`` (k, 3)."""
        P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(P), dtype=np.int64)
        if len(P) and self._cells is not None:
            self.bin_around(P)
            y0, z0, hy, hz = self._cells[:4]
            _query_kernel(P, self.V, self.F, self._g, y0, z0, hy, hz, *self._region,
                          *self._bins, out)  # fmt: skip
        return out

    def flood(
        self,
        points: npt.ArrayLike,
        adjacency: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
        seeds: npt.ArrayLike,
        transform: npt.ArrayLike | None = None,
    ) -> npt.NDArray[np.int64]:
        """Vertices of another mesh inside this surface, reached from ``seeds``.

        ``points`` (n, 3): that mesh's vertices in its own frame; ``transform`` (4, 4):
        the rigid map from that frame into this surface's (None: the same);
        ``adjacency``: its vertex adjacency, CSR ``(indptr, indices)``. The seeds are
        tested, then the neighbours not tested yet of those inside, batch by batch, each
        batch in the order of the vertices, until one has none inside: a region of the
        other mesh inside this one is found whole from any vertex of it. Compiled (one
        pass, the winding numbers as `__call__` gives them); a batch beyond the cells
        binned bins them and is asked again. Returns the vertices inside, in the order
        found.
        """
        B = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        T = np.eye(4) if transform is None else np.asarray(transform, dtype=np.float64)
        R, t = np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3])
        ip = np.ascontiguousarray(adjacency[0], dtype=np.int64)
        ix = np.ascontiguousarray(adjacency[1], dtype=np.int64)
        rows = np.ascontiguousarray(seeds, dtype=np.int64).ravel()
        if not len(rows) or self._cells is None:
            return np.zeros(0, dtype=np.int64)
        tested = np.zeros(len(B), dtype=np.bool_)
        tested[rows] = True
        found: list[npt.NDArray[np.int64]] = []
        while len(rows):
            y0, z0, hy, hz = self._cells[:4]
            inside = np.empty(len(B), dtype=np.int64)
            k, rows = _flood_kernel(
                rows, B, R, t, ip, ix, tested, self.V, self.F, self._g, y0, z0, hy, hz,
                *self._region, *self._bins, inside,
            )  # fmt: skip
            found.append(inside[:k])
            if len(rows):
                # a cell further out than the binned ones (a cell more: the kernel places
                # the points by its own rounding)
                self.bin_around(B[rows] @ R.T + t, margin=1)
        return np.concatenate(found)


@numba.njit(cache=True)
def _edge_sign(V, u, v, py, pz):  # noqa: ANN001, ANN202 # pragma: no cover
    """Side of the point (py, pz) of the directed edge u -> v in the yz plane: +1, -1 or 0.

    0 only for an edge that projects to a point. Computed from the lower-numbered end,
    the same for both faces of the edge; a tie takes the sign of the point shifted by
    (e, e**2).
    """
    flip = 1
    if u > v:
        u, v = v, u
        flip = -1
    dy = V[v, 1] - V[u, 1]
    dz = V[v, 2] - V[u, 2]
    f = dy * (pz - V[u, 2]) - dz * (py - V[u, 1])
    if f == 0.0:
        f = -dz if dz != 0.0 else dy
    if f > 0.0:
        return flip
    if f < 0.0:
        return -flip
    return 0


@numba.njit(cache=True)
def _cells_kernel(V, g):  # noqa: ANN001, ANN202 # pragma: no cover
    # the g x g grid over the surface's yz box (y0, z0, hy, hz) and each vertex's cell;
    # a face's cells are the range of its vertices' (a coordinate's cell is monotone in
    # it: the same range as from the face's own yz box)
    # (element loops: numpy's min and max compiled here took 0.35 s of a first run)
    y0, z0, y1, z1 = V[0, 1], V[0, 2], V[0, 1], V[0, 2]
    for v in range(1, V.shape[0]):
        y0, y1 = min(y0, V[v, 1]), max(y1, V[v, 1])
        z0, z1 = min(z0, V[v, 2]), max(z1, V[v, 2])
    hy = (y1 - y0) / g
    hz = (z1 - z0) / g
    if hy <= 0.0:
        hy = 1.0
    if hz <= 0.0:
        hz = 1.0
    n = V.shape[0]
    cy = np.empty(n, dtype=np.int64)
    cz = np.empty(n, dtype=np.int64)
    for v in range(n):
        cy[v] = min(g - 1, int((V[v, 1] - y0) / hy))
        cz[v] = min(g - 1, int((V[v, 2] - z0) / hz))
    return y0, z0, hy, hz, cy, cz


@numba.njit(cache=True)
def _region_kernel(P, g, y0, z0, hy, hz):  # noqa: ANN001, ANN202 # pragma: no cover
    # the range of cells (i0, i1, j0, j1) that queries of the points P look in
    i0, i1, j0, j1 = g - 1, 0, g - 1, 0
    for q in range(P.shape[0]):
        i = min(g - 1, int(max(P[q, 1] - y0, 0.0) / hy))
        j = min(g - 1, int(max(P[q, 2] - z0, 0.0) / hz))
        i0, i1, j0, j1 = min(i0, i), max(i1, i), min(j0, j), max(j1, j)
    return i0, i1, j0, j1


@numba.njit(cache=True)
def _face_cells(F, cy, cz, t, i0, i1, j0, j1):  # noqa: ANN001, ANN202 # pragma: no cover
    # face t's range of cells clipped to [i0, i1] x [j0, j1], from the region's corner
    # (an empty range where it lies outside)
    a, b, c = F[t, 0], F[t, 1], F[t, 2]
    return (
        max(min(cy[a], cy[b], cy[c]), i0) - i0,
        min(max(cy[a], cy[b], cy[c]), i1) - i0,
        max(min(cz[a], cz[b], cz[c]), j0) - j0,
        min(max(cz[a], cz[b], cz[c]), j1) - j0,
    )


@numba.njit(cache=True)
def _bin_kernel(F, cy, cz, i0, i1, j0, j1):  # noqa: ANN001, ANN202 # pragma: no cover
    # the faces binned by their cell ranges in the cells [i0, i1] x [j0, j1] (as
    # `bin_boxes` bins them: cell (i, j) at (i - i0) * (j1 - j0 + 1) + j - j0, each in face
    # order); a face outside them in none. Each face's range is taken again in the second
    # pass rather than kept (a pass over F, not over a table six times its size)
    m = F.shape[0]
    nj = j1 - j0 + 1
    start = np.empty((i1 - i0 + 1) * nj + 1, dtype=np.int64)
    for k in range(start.shape[0]):
        start[k] = 0
    for t in range(m):
        lo_i, hi_i, lo_j, hi_j = _face_cells(F, cy, cz, t, i0, i1, j0, j1)
        for i in range(lo_i, hi_i + 1):
            for j in range(lo_j, hi_j + 1):
                start[i * nj + j + 1] += 1
    for k in range(len(start) - 1):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    items = np.empty(start[-1], dtype=np.int64)
    for t in range(m):
        lo_i, hi_i, lo_j, hi_j = _face_cells(F, cy, cz, t, i0, i1, j0, j1)
        for i in range(lo_i, hi_i + 1):
            for j in range(lo_j, hi_j + 1):
                k = i * nj + j
                items[fill[k]] = t
                fill[k] += 1
    return start, items


@numba.njit(cache=True)
def bin_boxes(boxes, n0, n1, n2):  # noqa: ANN001, ANN201 # pragma: no cover
    """Items binned in a grid of ``n0 x n1 x n2`` cells, each in every cell of its box.

    ``boxes`` (m, 6) int64: per item its cell ranges, inclusive (i0, i1, j0, j1, k0,
    k1). Returns the CSR of the cells (cell ``(i * n1 + j) * n2 + k``): ``start``
    (n0 * n1 * n2 + 1,) and ``items``, each cell's items in order.
    """
    m = boxes.shape[0]
    start = np.empty(n0 * n1 * n2 + 1, dtype=np.int64)
    for c in range(start.shape[0]):
        start[c] = 0
    for t in range(m):
        k0, k1 = boxes[t, 4], boxes[t, 5] + 1
        for i in range(boxes[t, 0], boxes[t, 1] + 1):
            for j in range(boxes[t, 2], boxes[t, 3] + 1):
                row = (i * n1 + j) * n2 + 1
                for k in range(row + k0, row + k1):
                    start[k] += 1
    for c in range(n0 * n1 * n2):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    items = np.empty(start[-1], dtype=np.int64)
    for t in range(m):
        k0, k1 = boxes[t, 4], boxes[t, 5] + 1
        for i in range(boxes[t, 0], boxes[t, 1] + 1):
            for j in range(boxes[t, 2], boxes[t, 3] + 1):
                row = (i * n1 + j) * n2
                for c in range(row + k0, row + k1):
                    items[fill[c]] = t
                    fill[c] += 1
    return start, items


@numba.njit(cache=True)
def _query_kernel(P, V, F, g, y0, z0, hy, hz, i0, i1, j0, j1, count, cells, out):  # noqa: ANN001, ANN202 # pragma: no cover
    # every point's cell is binned (`WindingGrid.bin_around`)
    y1 = y0 + g * hy
    z1 = z0 + g * hz
    nj = j1 - j0 + 1
    for q in range(P.shape[0]):
        px, py, pz = P[q, 0], P[q, 1], P[q, 2]
        if not (y0 <= py <= y1 and z0 <= pz <= z1):
            continue  # the ray misses the surface's box
        i = min(g - 1, int((py - y0) / hy))
        j = min(g - 1, int((pz - z0) / hz))
        cell = (i - i0) * nj + j - j0
        w = 0
        for k in range(count[cell], count[cell + 1]):
            t = cells[k]
            a, b, c = F[t, 0], F[t, 1], F[t, 2]
            s = _edge_sign(V, b, c, py, pz)
            if s == 0 or _edge_sign(V, c, a, py, pz) != s or _edge_sign(V, a, b, py, pz) != s:
                continue
            # crossing: is it beyond the point? the hit's x, weighted by the (positive,
            # up to s) edge functions, against the point's
            wa = (V[c, 1] - V[b, 1]) * (pz - V[b, 2]) - (V[c, 2] - V[b, 2]) * (py - V[b, 1])
            wb = (V[a, 1] - V[c, 1]) * (pz - V[c, 2]) - (V[a, 2] - V[c, 2]) * (py - V[c, 1])
            wc = (V[b, 1] - V[a, 1]) * (pz - V[a, 2]) - (V[b, 2] - V[a, 2]) * (py - V[a, 1])
            tot = wa + wb + wc
            if tot == 0.0:
                continue  # a face seen edge-on: no area to cross
            ahead = (wa * (V[a, 0] - px) + wb * (V[b, 0] - px) + wc * (V[c, 0] - px)) / tot
            if ahead > 0.0:
                w += s
        out[q] = w


@numba.njit(cache=True)
def _flood_kernel(
    rows, BV, R, t, ip, ix, tested, V, F, g, y0, z0, hy, hz, i0, i1, j0, j1, count, cells, inside
):  # noqa: ANN001, ANN202, E501 # pragma: no cover
    # batch by batch: the rows' winding numbers about the surface (V, F; its grid binned in
    # cells [i0, i1] x [j0, j1]), those inside kept in order, then their neighbours not
    # tested yet (in index order) as the next batch. Returns how many were kept and, where a
    # batch has a point beyond the cells binned, that batch (untested), else an empty one
    k = 0
    one = np.empty((1, 3))
    w = np.empty(1, dtype=np.int64)
    nxt = np.empty(BV.shape[0], dtype=np.int64)
    fresh = np.empty(BV.shape[0], dtype=np.bool_)
    for v in range(BV.shape[0]):
        fresh[v] = False
    while rows.shape[0]:
        hit = np.empty(rows.shape[0], dtype=np.bool_)  # every entry written below
        for q in range(rows.shape[0]):
            r = rows[q]
            for a in range(3):
                one[0, a] = R[a, 0] * BV[r, 0] + R[a, 1] * BV[r, 1] + R[a, 2] * BV[r, 2] + t[a]
            py, pz = one[0, 1], one[0, 2]
            if y0 <= py <= y0 + g * hy and z0 <= pz <= z0 + g * hz:
                i = min(g - 1, int((py - y0) / hy))
                j = min(g - 1, int((pz - z0) / hz))
                if i < i0 or i > i1 or j < j0 or j > j1:
                    return k, rows  # beyond the cells binned
            w[0] = 0
            _query_kernel(one, V, F, g, y0, z0, hy, hz, i0, i1, j0, j1, count, cells, w)
            hit[q] = w[0] > 0
        # the next batch in the order of the rows: marked, then read off between the
        # least and the largest (no sort to compile)
        lo, hi = BV.shape[0], -1
        for q in range(rows.shape[0]):
            if hit[q]:
                inside[k] = rows[q]
                k += 1
                for p in range(ip[rows[q]], ip[rows[q] + 1]):
                    v = ix[p]
                    if not tested[v]:
                        tested[v] = True
                        fresh[v] = True
                        lo, hi = min(lo, v), max(hi, v)
        n = 0
        for v in range(lo, hi + 1):
            if fresh[v]:
                fresh[v] = False
                nxt[n] = v
                n += 1
        rows = nxt[:n].copy()
    return k, rows
