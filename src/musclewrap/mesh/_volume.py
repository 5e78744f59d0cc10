"""Signed volume of a closed triangle mesh, its gradient, and its cubic along a line."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = ["volume", "volume_cubic", "volume_gradient"]


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
    c = V.mean(axis=0) if center is None else center
    P = V - c
    a, b, cc = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, cc)) / 6.0)


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
    c = V.mean(axis=0)
    P = V - c
    a, b, cc = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    n = V.shape[0]
    G = np.empty((n, 3))
    ga = np.cross(b, cc)
    gb = np.cross(cc, a)
    gc = np.cross(a, b)
    for k in range(3):
        G[:, k] = (
            np.bincount(F[:, 0], ga[:, k], minlength=n)
            + np.bincount(F[:, 1], gb[:, k], minlength=n)
            + np.bincount(F[:, 2], gc[:, k], minlength=n)
        )
    return G / 6.0


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
    Aa, Ab, Ac = A[F[:, 0]], A[F[:, 1]], A[F[:, 2]]
    Ba, Bb, Bc = B[F[:, 0]], B[F[:, 1]], B[F[:, 2]]
    cAA = np.cross(Ab, Ac)
    cBB = np.cross(Bb, Bc)
    cmix = np.cross(Ab, Bc) + np.cross(Bb, Ac)
    c0 = np.einsum("ij,ij->", Aa, cAA)
    c1 = np.einsum("ij,ij->", Ba, cAA) + np.einsum("ij,ij->", Aa, cmix)
    c2 = np.einsum("ij,ij->", Aa, cBB) + np.einsum("ij,ij->", Ba, cmix)
    c3 = np.einsum("ij,ij->", Ba, cBB)
    return np.array([c0, c1, c2, c3]) / 6.0
