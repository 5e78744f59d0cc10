"""Signed volume of a closed triangle mesh, its gradient, and its cubic along a line."""

from __future__ import annotations

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ._geometry import face_areas

__all__ = [
    "combine_pair",
    "mean_rows",
    "volume",
    "volume_cubic",
    "volume_cubic_pair",
    "volume_gradient",
    "volume_hessian_reduced",
]


@numba.njit(cache=True)
def _mean_rows_kernel(V):  # pragma: no cover - compiled
    s0 = s1 = s2 = 0.0
    for i in range(V.shape[0]):
        s0 += V[i, 0]
        s1 += V[i, 1]
        s2 += V[i, 2]
    n = max(V.shape[0], 1)
    return np.array([s0 / n, s1 / n, s2 / n])


def mean_rows(V: FloatArray) -> FloatArray:
    """Mean of the rows of an (n, 3) array, like ``V.mean(axis=0)`` but one compiled pass.

    numpy reduces an (n, 3) array along axis 0 through a slow strided loop:
    103 us for 6,400 rows against 7 us here (`python benchmarks/speed/bench_kernels.py`).
    """
    return _mean_rows_kernel(np.ascontiguousarray(V, dtype=np.float64))


def volume(V: FloatArray, F: IntArray, *, center: FloatArray | None = None) -> float:
    """Signed volume enclosed by a closed, outward-oriented triangle mesh.

    Parameters
    ----------
    V : (n, 3) float64 array
        Vertex positions.
    F : (m, 3) int array
        Triangles, counter-clockwise seen from outside.
    center : (3,) float64 array, optional
        Apex of the tetrahedra. The result does not depend on it analytically,
        but rounding does: the default (the vertex mean) keeps the sum well
        conditioned for meshes far from the origin (CT frames).

    Returns
    -------
    float
        ``sum_f det(a, b, c) / 6`` over the faces; positive when outward.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> round(volume(V, F), 12)
    0.166666666667
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    c = mean_rows(V) if center is None else np.asarray(center, dtype=np.float64)
    return float(
        _volume_kernel(
            np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64), c
        )
    )


def mean_thickness(V: FloatArray, F: IntArray, vol: float | None = None) -> float:
    """A closed surface's mean thickness ``4 V / A`` (a cylinder's diameter, a slab's thickness).

    ``vol``: its volume where already known (else computed).
    """
    vol = volume(V, F) if vol is None else vol
    return 4.0 * abs(vol) / float(face_areas(V, F).sum())


def volume_gradient(V: FloatArray, F: IntArray) -> FloatArray:
    """Gradient of `volume` with respect to every vertex coordinate.

    Parameters
    ----------
    V : (n, 3) float64 array
        Vertex positions.
    F : (m, 3) int array
        Triangles.

    Returns
    -------
    (n, 3) float64 array
        ``dV/dv_i = 1/6 * sum over faces (i, j, k) of v_j x v_k`` (eq. 13 of
        Kohout et al. 2012); translation invariant for a closed mesh.
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    return _gradient_kernel(V, np.ascontiguousarray(F, dtype=np.int64), mean_rows(V))


# (row, column, third) coordinate index triples, each with Levi-Civita sign +1
_CROSS = ((0, 1, 2), (1, 2, 0), (2, 0, 1))


def volume_hessian_reduced(V: FloatArray, F: IntArray, W: FloatArray) -> FloatArray:
    """Hessian of the volume of ``W x`` with respect to ``x``, at ``V = W x``.

    Parameters
    ----------
    V : (n, 3) float64 array
        Current vertex positions (``W x``, centred or not: the volume of a
        closed mesh does not depend on the origin).
    F : (m, 3) int array
        Triangles.
    W : (n, k) float64 array
        Coordinates of the vertices in the ``k`` control points.

    Returns
    -------
    (3k, 3k) float64 array
        Symmetric; rows and columns ordered control point by control point,
        x, y, z within each (``x.ravel()`` of a ``(k, 3)`` array).

    Notes
    -----
    Per face ``(a, b, c)`` the volume is ``a . (b x c) / 6``; the block of
    its Hessian for vertices ``(i, j)`` with third vertex ``l`` is
    ``-eps(i, j, l) [v_l]_x / 6`` (``[v]_x`` the cross-product matrix, eps the
    sign of the permutation of the face's vertices). The mesh Hessian is
    sparse; its coordinate components ``(r, s)`` vanish for ``r == s``, and
    ``(s, r)`` is the transpose of ``(r, s)`` (symmetry), so three reductions
    ``W^T H_rs W`` give all of it.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    from scipy import sparse

    a, b, c = F.T
    rows = np.concatenate([a, b, c, a, b, c])
    cols = np.concatenate([b, c, a, c, a, b])
    third = np.concatenate([c, a, b, b, c, a])
    perm = np.repeat([1.0, 1.0, 1.0, -1.0, -1.0, -1.0], len(F))
    n, k = W.shape
    K = np.zeros((k, 3, k, 3))
    for r, s, t in _CROSS:
        # [v]_x has entry (r, s) = -eps(r, s, t) v_t
        H = sparse.csr_matrix((perm * V[third, t] / 6.0, (rows, cols)), shape=(n, n))
        K[:, r, :, s] = W.T @ (H @ W)
        K[:, s, :, r] = K[:, r, :, s].T
    return K.reshape(3 * k, 3 * k)


def volume_cubic(A: FloatArray, B: FloatArray, F: IntArray) -> FloatArray:
    """Coefficients of the volume of ``A + t * B`` as a cubic polynomial in ``t``.

    Parameters
    ----------
    A, B : (n, 3) float64 arrays
        Base positions (best centred near the origin) and a direction.
    F : (m, 3) int array
        Triangles.

    Returns
    -------
    (4,) float64 array
        ``c`` with ``volume(A + t B) = c[0] + c[1] t + c[2] t**2 + c[3] t**3``.

    Notes
    -----
    The determinant of three affine functions of ``t`` expands exactly, so a
    line search on the volume needs one evaluation of this cubic instead of
    repeated volume evaluations; its root is the exact volume correction.
    """
    # one kernel serves both forms: volume(A + tB) is the pair form of [A, -B]
    return _cubic_pair_kernel(np.hstack([A, -B]), np.ascontiguousarray(F, dtype=np.int64))


# The face loops may fuse multiplies and adds and reorder the additions of one face's
# terms: the volume cubic is 1.2-2x faster (`python benchmarks/speed/bench_kernels.py`, item 4),
# and its coefficients move by about 5e-15 relative. Without the other fast-math flags, so
# NaN and infinity still propagate and are caught.
_FACE_MATH = {"contract", "reassoc"}


@numba.njit(fastmath=_FACE_MATH, cache=True)
def _det(ax, ay, az, bx, by, bz, cx, cy, cz):  # pragma: no cover - compiled
    return ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)


# Reductions over faces split them into this many fixed chunks (run in parallel) and
# add the partial sums in order: the result is the same bit for bit on any number of
# threads.
_CHUNKS = 16


def _volume_py(V, F, c):  # noqa: ANN001, ANN202 # pragma: no cover - compiled
    m = F.shape[0]
    part = np.empty(_CHUNKS)  # each chunk's sum (every entry written)
    for ch in numba.prange(_CHUNKS):
        s = 0.0
        for f in range(ch * m // _CHUNKS, (ch + 1) * m // _CHUNKS):
            a, b, d = F[f, 0], F[f, 1], F[f, 2]
            s += _det(
                V[a, 0] - c[0],
                V[a, 1] - c[1],
                V[a, 2] - c[2],
                V[b, 0] - c[0],
                V[b, 1] - c[1],
                V[b, 2] - c[2],
                V[d, 0] - c[0],
                V[d, 1] - c[1],
                V[d, 2] - c[2],
            )
        part[ch] = s
    total = 0.0
    for ch in range(_CHUNKS):
        total += part[ch]
    return total / 6.0


@numba.njit(fastmath=_FACE_MATH, cache=True)
def _gradient_kernel(V, F, c):  # pragma: no cover - compiled
    # d/da det(a, b, d) = b x d, and cyclically; scalars only (no array per face)
    G = np.empty((V.shape[0], 3))
    for i in range(V.shape[0]):
        G[i, 0] = G[i, 1] = G[i, 2] = 0.0
    for f in range(F.shape[0]):
        a, b, d = F[f, 0], F[f, 1], F[f, 2]
        ax, ay, az = V[a, 0] - c[0], V[a, 1] - c[1], V[a, 2] - c[2]
        bx, by, bz = V[b, 0] - c[0], V[b, 1] - c[1], V[b, 2] - c[2]
        dx, dy, dz = V[d, 0] - c[0], V[d, 1] - c[1], V[d, 2] - c[2]
        G[a, 0] += (by * dz - bz * dy) / 6.0
        G[a, 1] += (bz * dx - bx * dz) / 6.0
        G[a, 2] += (bx * dy - by * dx) / 6.0
        G[b, 0] += (dy * az - dz * ay) / 6.0
        G[b, 1] += (dz * ax - dx * az) / 6.0
        G[b, 2] += (dx * ay - dy * ax) / 6.0
        G[d, 0] += (ay * bz - az * by) / 6.0
        G[d, 1] += (az * bx - ax * bz) / 6.0
        G[d, 2] += (ax * by - ay * bx) / 6.0
    return G


def _cubic_pair_py(XU, F):  # pragma: no cover - compiled
    # volume of XU[:, :3] - t * XU[:, 3:] as a cubic in t, read in place
    m = F.shape[0]
    part = np.empty((_CHUNKS, 4))  # each chunk's sums (every entry written)
    for ch in numba.prange(_CHUNKS):
        p0 = 0.0
        p1 = 0.0
        p2 = 0.0
        p3 = 0.0
        for f in range(ch * m // _CHUNKS, (ch + 1) * m // _CHUNKS):
            a, b, d = F[f, 0], F[f, 1], F[f, 2]
            ab0, ab1, ab2 = XU[b, 0], XU[b, 1], XU[b, 2]
            ad0, ad1, ad2 = XU[d, 0], XU[d, 1], XU[d, 2]
            bb0, bb1, bb2 = -XU[b, 3], -XU[b, 4], -XU[b, 5]
            bd0, bd1, bd2 = -XU[d, 3], -XU[d, 4], -XU[d, 5]
            aax = ab1 * ad2 - ab2 * ad1
            aay = ab2 * ad0 - ab0 * ad2
            aaz = ab0 * ad1 - ab1 * ad0
            bbx = bb1 * bd2 - bb2 * bd1
            bby = bb2 * bd0 - bb0 * bd2
            bbz = bb0 * bd1 - bb1 * bd0
            mx = ab1 * bd2 - ab2 * bd1 + bb1 * ad2 - bb2 * ad1
            my = ab2 * bd0 - ab0 * bd2 + bb2 * ad0 - bb0 * ad2
            mz = ab0 * bd1 - ab1 * bd0 + bb0 * ad1 - bb1 * ad0
            a0, a1, a2 = XU[a, 0], XU[a, 1], XU[a, 2]
            b0, b1, b2 = -XU[a, 3], -XU[a, 4], -XU[a, 5]
            p0 += a0 * aax + a1 * aay + a2 * aaz
            p1 += b0 * aax + b1 * aay + b2 * aaz + a0 * mx + a1 * my + a2 * mz
            p2 += a0 * bbx + a1 * bby + a2 * bbz + b0 * mx + b1 * my + b2 * mz
            p3 += b0 * bbx + b1 * bby + b2 * bbz
        part[ch, 0], part[ch, 1], part[ch, 2], part[ch, 3] = p0, p1, p2, p3
    out = np.empty(4)
    for k in range(4):
        s = 0.0
        for ch in range(_CHUNKS):
            s += part[ch, k]
        out[k] = s / 6.0
    return out


# Each reduction is compiled twice: threads pay off from about 10K faces (1.2-2x faster
# alone on the capsule's 30K faces in runs of `python benchmarks/speed/bench_kernels.py`, item 4);
# below that the start of a parallel region costs more than it saves. Inside a whole pose of
# 15-30K faces the two differ by 2 % at most (item 6). The chunks are the same either way,
# and so is every bit of the sum.
_PARALLEL_FACES = 10000
_volume_par = numba.njit(parallel=True, fastmath=_FACE_MATH, cache=True)(_volume_py)
_volume_ser = numba.njit(fastmath=_FACE_MATH, cache=True)(_volume_py)
_cubic_pair_par = numba.njit(parallel=True, fastmath=_FACE_MATH, cache=True)(_cubic_pair_py)
_cubic_pair_ser = numba.njit(fastmath=_FACE_MATH, cache=True)(_cubic_pair_py)


def _volume_kernel(V, F, c):  # noqa: ANN001, ANN202
    return (_volume_par if F.shape[0] >= _PARALLEL_FACES else _volume_ser)(V, F, c)


def _cubic_pair_kernel(XU, F):  # noqa: ANN001, ANN202
    return (_cubic_pair_par if F.shape[0] >= _PARALLEL_FACES else _cubic_pair_ser)(XU, F)


def volume_cubic_pair(XU: FloatArray, F: IntArray) -> FloatArray:
    """`volume_cubic` of ``XU[:, :3] - t * XU[:, 3:]`` without copying the halves.

    Parameters
    ----------
    XU : (n, 6) float64 array, C-contiguous
        Base positions and direction side by side (one product ``W @ [x, u]``).
    F : (m, 3) int array
        Triangles.

    Returns
    -------
    (4,) float64 array
        Cubic coefficients in ``t``.
    """
    return _cubic_pair_kernel(np.ascontiguousarray(XU), np.ascontiguousarray(F, dtype=np.int64))


@numba.njit(cache=True)
def _combine_kernel(XU, t, c):  # pragma: no cover - compiled
    V = np.empty((XU.shape[0], 3))
    for i in range(XU.shape[0]):
        for k in range(3):
            V[i, k] = (XU[i, k] - t * XU[i, 3 + k]) + c[k]
    return V


def combine_pair(XU: FloatArray, t: float, c: FloatArray) -> FloatArray:
    """Positions ``XU[:, :3] - t * XU[:, 3:] + c`` as a new contiguous (n, 3) array.

    One compiled pass, where numpy made three over the strided halves.
    """
    return _combine_kernel(
        np.ascontiguousarray(XU, dtype=np.float64), float(t), np.asarray(c, dtype=np.float64)
    )
