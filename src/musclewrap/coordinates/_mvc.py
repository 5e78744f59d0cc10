"""Mean value coordinates of points with respect to a closed triangle cage."""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from .._validation import as_faces, as_points
from ..constants import tol

__all__ = ["mean_value_coordinates", "rows_dot"]


def mean_value_coordinates(
    P: npt.ArrayLike,
    C: npt.ArrayLike,
    CF: npt.ArrayLike,
    *,
    chunk: int = 65536,
) -> FloatArray:
    """Mean value coordinates of points in a closed triangle cage (Ju et al. 2005).

    Parameters
    ----------
    P : (n, 3) array_like
        Query points, inside or outside the cage (the coordinates extend
        smoothly outside a closed cage).
    C : (m, 3) array_like
        Cage vertices.
    CF : (k, 3) array_like
        Cage triangles, consistently oriented.
    chunk : int, optional
        Points processed per block (bounds the temporary memory).

    Returns
    -------
    (n, m) float64 array
        ``W`` with rows summing to 1 and ``W @ C == P`` up to rounding.

    Notes
    -----
    Follows the pseudocode of Ju, Schaefer & Warren (2005), section 3.3, with
    its two special cases: a point on a cage vertex gets that vertex's
    one-hot row, a point on a cage face gets the face's barycentric row; a
    face whose plane contains the point but which does not contain it
    contributes nothing. ``c`` is clamped to [-1, 1] before ``sqrt(1 - c**2)``.

    References
    ----------
    .. [1] T. Ju, S. Schaefer, J. Warren, "Mean value coordinates for closed
       triangular meshes", ACM Trans. Graph. 24(3), 561-566, 2005.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> CF = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> W = mean_value_coordinates([[0.1, 0.2, 0.3]], C, CF)
    >>> bool(np.allclose(W @ C, [[0.1, 0.2, 0.3]])), bool(np.isclose(W.sum(), 1.0))
    (True, True)
    """
    P = as_points(P, "P")
    C = as_points(C, "C", min_rows=4)
    CF = as_faces(CF, len(C), "CF")
    n, m = len(P), len(C)
    W = np.empty((n, m))
    for start in range(0, n, chunk):
        W[start : start + chunk] = _mvc_block(P[start : start + chunk], C, CF)
    return W


@numba.njit(parallel=True, cache=True, fastmath=False)
def _mvc_kernel(P, C, CF, E, FE, eps_vertex, eps_face, eps_plane, W):  # pragma: no cover - compiled
    n = P.shape[0]
    m = C.shape[0]
    k = CF.shape[0]
    ne = E.shape[0]
    for r in numba.prange(n):
        px, py, pz = P[r, 0], P[r, 1], P[r, 2]
        d = np.empty(m)
        U = np.empty((m, 3))
        th = np.empty(ne)
        st = np.empty(ne)
        ct = np.empty(ne)
        hit_vertex = -1
        for j in range(m):
            dx, dy, dz = C[j, 0] - px, C[j, 1] - py, C[j, 2] - pz
            dj = np.sqrt(dx * dx + dy * dy + dz * dz)
            d[j] = dj
            if dj < eps_vertex:
                hit_vertex = j
                break
            U[j, 0], U[j, 1], U[j, 2] = dx / dj, dy / dj, dz / dj
        for j in range(m):
            W[r, j] = 0.0
        if hit_vertex >= 0:
            W[r, hit_vertex] = 1.0
            continue
        # angle subtended by every cage edge, once per edge (two faces share it);
        # atan2 of |u x v| and u.v stays accurate near 0 and pi
        for e in range(ne):
            a, b = E[e, 0], E[e, 1]
            cx = U[a, 1] * U[b, 2] - U[a, 2] * U[b, 1]
            cy = U[a, 2] * U[b, 0] - U[a, 0] * U[b, 2]
            cz = U[a, 0] * U[b, 1] - U[a, 1] * U[b, 0]
            sn = np.sqrt(cx * cx + cy * cy + cz * cz)
            cs = U[a, 0] * U[b, 0] + U[a, 1] * U[b, 1] + U[a, 2] * U[b, 2]
            th[e] = np.arctan2(sn, cs)
            rn = np.sqrt(sn * sn + cs * cs)
            st[e] = sn / rn
            ct[e] = cs / rn
        hit_face = -1
        total = 0.0
        for f in range(k):
            i0, i1, i2 = CF[f, 0], CF[f, 1], CF[f, 2]
            e0, e1, e2 = FE[f, 0], FE[f, 1], FE[f, 2]
            th0, th1, th2 = th[e0], th[e1], th[e2]
            h = 0.5 * (th0 + th1 + th2)
            if np.pi - h < eps_face:
                hit_face = f
                break
            sh = np.sin(h)
            ch = np.cos(h)
            s0, s1, s2 = st[e0], st[e1], st[e2]
            # sin(h - th_i) = sin h cos th_i - cos h sin th_i
            c0 = 2.0 * sh * (sh * ct[e0] - ch * s0) / (s1 * s2) - 1.0
            c1 = 2.0 * sh * (sh * ct[e1] - ch * s1) / (s2 * s0) - 1.0
            c2 = 2.0 * sh * (sh * ct[e2] - ch * s2) / (s0 * s1) - 1.0
            det = (
                U[i0, 0] * (U[i1, 1] * U[i2, 2] - U[i1, 2] * U[i2, 1])
                - U[i0, 1] * (U[i1, 0] * U[i2, 2] - U[i1, 2] * U[i2, 0])
                + U[i0, 2] * (U[i1, 0] * U[i2, 1] - U[i1, 1] * U[i2, 0])
            )
            # sin psi_i (signed) by the spherical law of sines: det is sin psi_i times the
            # sines of the two arcs at u_i (no sqrt(1 - c_i^2), which loses digits near 0)
            q0 = det / (s1 * s2)
            q1 = det / (s2 * s0)
            q2 = det / (s0 * s1)
            if abs(q0) <= eps_plane or abs(q1) <= eps_plane or abs(q2) <= eps_plane:
                continue  # the point lies (nearly) on this face's plane, outside the face
            w0 = (th0 - c1 * th2 - c2 * th1) / (d[i0] * s1 * q2)
            w1 = (th1 - c2 * th0 - c0 * th2) / (d[i1] * s2 * q0)
            w2 = (th2 - c0 * th1 - c1 * th0) / (d[i2] * s0 * q1)
            W[r, i0] += w0
            W[r, i1] += w1
            W[r, i2] += w2
            total += w0 + w1 + w2
        if hit_face >= 0:
            for j in range(m):
                W[r, j] = 0.0
            i0, i1, i2 = CF[hit_face, 0], CF[hit_face, 1], CF[hit_face, 2]
            # barycentric coordinates in the face's plane
            ax, ay, az = C[i0, 0], C[i0, 1], C[i0, 2]
            bx, by, bz = C[i1, 0] - ax, C[i1, 1] - ay, C[i1, 2] - az
            cx, cy, cz = C[i2, 0] - ax, C[i2, 1] - ay, C[i2, 2] - az
            qx, qy, qz = px - ax, py - ay, pz - az
            d00 = bx * bx + by * by + bz * bz
            d01 = bx * cx + by * cy + bz * cz
            d11 = cx * cx + cy * cy + cz * cz
            d20 = qx * bx + qy * by + qz * bz
            d21 = qx * cx + qy * cy + qz * cz
            den = d00 * d11 - d01 * d01
            wb = (d11 * d20 - d01 * d21) / den
            wc = (d00 * d21 - d01 * d20) / den
            W[r, i0] = 1.0 - wb - wc
            W[r, i1] = wb
            W[r, i2] = wc
        else:
            for j in range(m):
                W[r, j] /= total


def _mvc_block(
    P: FloatArray, C: FloatArray, CF: IntArray, in_plane: float = tol.mvc_in_plane
) -> FloatArray:
    """Coordinates of ``P``; ``in_plane`` other than the tolerance: its benchmark only."""
    diag = float(np.linalg.norm(C.max(0) - C.min(0)))
    E, FE = _face_edges(CF)
    W = np.empty((len(P), len(C)))
    _mvc_kernel(P, C, CF, E, FE, tol.mvc_on_vertex * diag, tol.mvc_on_face, in_plane, W)
    return W


def _face_edges(CF: IntArray) -> tuple[IntArray, IntArray]:
    """Unique edges and, per face, the edge opposite each of its corners."""
    opp = np.stack([CF[:, [1, 2]], CF[:, [2, 0]], CF[:, [0, 1]]], axis=1)  # (k, 3, 2)
    keys = np.sort(opp.reshape(-1, 2), axis=1)
    E, inv = np.unique(keys, axis=0, return_inverse=True)
    return np.ascontiguousarray(E, dtype=np.int64), inv.reshape(-1, 3).astype(np.int64)


@numba.njit(parallel=True, fastmath=True, cache=True)
def _rows_dot_kernel(W, XT, out):  # pragma: no cover - compiled
    # six columns at once: each entry of W is loaded once and feeds six independent
    # sums (1.5x faster than six separate dot products per row on the capsule:
    # `python benchmarks/speed/bench_kernels.py`)
    n, m = W.shape
    for r in numba.prange(n):
        s0 = s1 = s2 = s3 = s4 = s5 = 0.0
        for j in range(m):
            w = W[r, j]
            s0 += w * XT[0, j]
            s1 += w * XT[1, j]
            s2 += w * XT[2, j]
            s3 += w * XT[3, j]
            s4 += w * XT[4, j]
            s5 += w * XT[5, j]
        out[r, 0] = s0
        out[r, 1] = s1
        out[r, 2] = s2
        out[r, 3] = s3
        out[r, 4] = s4
        out[r, 5] = s5


def rows_dot(W: FloatArray, X: npt.ArrayLike) -> FloatArray:
    """``W @ X`` for a tall coordinate matrix and a few columns (positions, directions).

    Every entry is one contiguous dot product of a row of ``W`` with a column
    of ``X``, so ``W`` is read once from memory; OpenBLAS is slow for 3-6
    right-hand columns (``musclewrap bench capsule`` prints both timings).

    Parameters
    ----------
    W : (n, m) float64 array
        Coordinates (e.g. `mean_value_coordinates`).
    X : (m, k) array_like
        Cage positions or directions, side by side.

    Returns
    -------
    (n, k) float64 array
    """
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[0] != W.shape[1]:
        raise ValueError(f"rows_dot: X must be ({W.shape[1]}, k), got {X.shape}")
    W = np.ascontiguousarray(W, dtype=np.float64)
    k = X.shape[1]
    out = np.empty((W.shape[0], k))
    if k == 6:  # the solver's case: no padding, no copy
        _rows_dot_kernel(W, np.ascontiguousarray(X.T), out)
        return out
    part = np.empty((W.shape[0], 6))
    for c0 in range(0, k, 6):  # columns in groups of six, the last one padded with zeros
        XT = np.zeros((6, X.shape[0]))
        XT[: min(6, k - c0)] = X[:, c0 : c0 + 6].T
        _rows_dot_kernel(W, XT, part)
        out[:, c0 : c0 + 6] = part[:, : min(6, k - c0)]
    return out
