"""How far each muscle's vertices are from the muscles beside it, within a reach.

What a picture of contact shows (`muscle_gaps`): per vertex the signed distance to
the nearest muscle it is kept apart from, negative inside it, exact up to ``reach``
and capped there. Only vertices within ``reach`` of another muscle's surface matter,
so each surface's faces are binned in a uniform grid (cells ``reach`` wide) and a
vertex is measured against the faces of the cells within ``reach`` of it (cells
farther than the nearest face found so far skipped), exactly (`_closest_on_triangle`);
the side by the surface's exact winding number (`WindingGrid`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ..mesh import WindingGrid, bin_boxes, in_box
from ._inside import _closest_on_triangle

__all__ = ["FacesWithin", "muscle_gaps"]

#: the most cells a surface's grid gets (wider cells beyond it)
_MAX_CELLS = 1 << 21


class FacesWithin:
    """Exact distances of points to a closed triangle surface, where they are within ``reach``.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        The surface.
    reach : float
        The distance beyond which a point is only reported as farther (mesh units).
    cell : float, optional
        The grid's cells' width (default ``reach``; wider where the grid would have more
        than `_MAX_CELLS`). The distances do not depend on it, only their time: on the
        LHDL walk and the gait2392 scene cells as wide as the reach were the quickest
        of 1, 1/2 and 1/3 of it (``benchmarks/speed/bench_view.py SCENE --phases``).
    """

    def __init__(self, V: FloatArray, F: IntArray, reach: float, cell: float | None = None) -> None:
        if not reach > 0:
            raise ValueError(f"reach must be positive, not {reach}")
        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        self.reach = float(reach)
        self.lo, self.hi = self.V.min(0), self.V.max(0)
        extent = self.hi - self.lo
        h = self.reach if cell is None else float(cell)
        if not h > 0:
            raise ValueError(f"cell must be positive, not {cell}")
        while np.prod(np.floor(extent / h) + 1) > _MAX_CELLS:
            h *= 2.0
        self.h = h
        self.dims = (np.floor(extent / h) + 1).astype(np.int64)
        self.start, self.cells = _bin_kernel(self.V, self.F, self.lo, h, self.dims)
        self._sides: WindingGrid | None = None

    def signed(self, P: FloatArray) -> FloatArray:
        """Each point's signed distance (negative inside), capped at +-``reach``.

        The side by the surface's exact winding number (`WindingGrid`, made when first
        needed); points outside the surface's box widened by ``reach`` are not looked at.
        """
        P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(P), self.reach)
        lo, hi = self.lo - self.reach, self.hi + self.reach
        near = in_box(P, lo, hi)
        if len(near):
            if self._sides is None:
                self._sides = WindingGrid(self.V, self.F)
            d = np.minimum(self(P[near]), self.reach)
            out[near] = np.where(self._sides(P[near]) != 0, -d, d)
        return out

    def __call__(self, P: FloatArray) -> FloatArray:
        """Each point's distance to the surface; ``inf`` where it is farther than ``reach``."""
        P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
        out = np.empty(len(P))
        stamp = np.full(len(self.F), -1, dtype=np.int64)
        _within_kernel(
            P, self.V, self.F, self.lo, self.h, self.dims, self.start, self.cells,
            self.reach, stamp, out,
        )  # fmt: skip
        return out


def muscle_gaps(
    surfaces: Mapping[str, tuple[FloatArray, IntArray]],
    pairs: Sequence[tuple[str, str]],
    reach: float,
    cell: float | None = None,
) -> dict[str, FloatArray]:
    """Per muscle, each vertex's signed distance to the nearest muscle it is paired with.

    ``surfaces`` (name -> ``V, F``) in one frame of reference; ``pairs`` the pairs
    kept apart (each both ways). Negative inside the other muscle; exact within
    ``reach``, capped at ``+reach`` beyond it and at ``-reach`` deeper than it. A
    muscle with non-finite positions takes no part (its vertices get ``reach``).
    ``cell``: as `FacesWithin`'s.
    """
    out = {n: np.full(len(V), float(reach)) for n, (V, _) in surfaces.items()}
    ok = {n for n, (V, _) in surfaces.items() if len(V) and np.isfinite(V).all()}
    within: dict[str, FacesWithin] = {}
    for a, b in sorted(pairs):
        for me, other in ((a, b), (b, a)):
            if me in ok and other in ok:
                if other not in within:
                    within[other] = FacesWithin(*surfaces[other], reach, cell)
                out[me] = np.minimum(out[me], within[other].signed(surfaces[me][0]))
    return out


@numba.njit(cache=True)
def _cell(x, lo, h, n):  # noqa: ANN001, ANN202 # pragma: no cover
    # the cell index of coordinate x along an axis, clipped to the grid
    i = int(np.floor((x - lo) / h))
    return min(max(i, 0), n - 1)


@numba.njit(cache=True)
def _bin_kernel(V, F, lo, h, dims):  # noqa: ANN001, ANN202 # pragma: no cover
    # each face in every cell its box touches: CSR (start, cells) over the cells
    m = F.shape[0]
    boxes = np.empty((m, 6), dtype=np.int64)
    for t in range(m):
        for k in range(3):
            a = min(V[F[t, 0], k], V[F[t, 1], k], V[F[t, 2], k])
            b = max(V[F[t, 0], k], V[F[t, 1], k], V[F[t, 2], k])
            boxes[t, 2 * k] = _cell(a, lo[k], h, dims[k])
            boxes[t, 2 * k + 1] = _cell(b, lo[k], h, dims[k])
    return bin_boxes(boxes, dims[0], dims[1], dims[2])


@numba.njit(cache=True)
def _box_gap(x, lo, h, i):  # noqa: ANN001, ANN202 # pragma: no cover
    # how far coordinate x lies outside cell i's span along an axis
    a = lo + i * h
    if x < a:
        return a - x
    b = a + h
    if x > b:
        return x - b
    return 0.0


@numba.njit(cache=True)
def _within_kernel(P, V, F, lo, h, dims, start, cells, reach, stamp, out):  # noqa: ANN001, ANN202 # pragma: no cover
    # per point, the nearest face among the cells within reach (a cell skipped when its box
    # lies beyond the nearest face found so far; a face tested once per point: stamp)
    n0, n1, n2 = dims[0], dims[1], dims[2]
    r2 = reach * reach
    for q in range(P.shape[0]):
        p0, p1, p2 = P[q, 0], P[q, 1], P[q, 2]
        best = r2
        i0 = int(np.floor((p0 - reach - lo[0]) / h))
        i1 = int(np.floor((p0 + reach - lo[0]) / h))
        j0 = int(np.floor((p1 - reach - lo[1]) / h))
        j1 = int(np.floor((p1 + reach - lo[1]) / h))
        k0 = int(np.floor((p2 - reach - lo[2]) / h))
        k1 = int(np.floor((p2 + reach - lo[2]) / h))
        for i in range(max(i0, 0), min(i1, n0 - 1) + 1):
            gx = _box_gap(p0, lo[0], h, i)
            for j in range(max(j0, 0), min(j1, n1 - 1) + 1):
                gy = _box_gap(p1, lo[1], h, j)
                for l in range(max(k0, 0), min(k1, n2 - 1) + 1):  # noqa: E741
                    gz = _box_gap(p2, lo[2], h, l)
                    if gx * gx + gy * gy + gz * gz >= best:
                        continue
                    c = (i * n1 + j) * n2 + l
                    for k in range(start[c], start[c + 1]):
                        t = cells[k]
                        if stamp[t] == q:
                            continue
                        stamp[t] = q
                        d = _closest_on_triangle(p0, p1, p2, V, F[t])[0]
                        if d < best:
                            best = d
        out[q] = np.sqrt(best) if best < r2 else np.inf
