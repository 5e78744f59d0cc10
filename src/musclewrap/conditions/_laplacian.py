"""Cotangent Laplacian of the cage (the shape condition)."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = ["cotangent_laplacian"]


def cotangent_laplacian(C: FloatArray, CF: IntArray, *, min_weight: float = 1e-2) -> FloatArray:
    """Row-normalized cotangent Laplacian, ``delta_i = sum_j w_ij c_j - c_i``.

    Parameters
    ----------
    C : (m, 3) float64 array
        Vertices of a closed triangle mesh (the rest cage).
    CF : (k, 3) int array
        Its triangles.
    min_weight : float, optional
        Cotangent weights are clamped from below at ``min_weight`` times the
        mean positive weight, so that obtuse triangles cannot make a row's
        weights cancel (which would blow up the condition number).

    Returns
    -------
    (m, m) float64 array
        ``L`` with ``L[i, i] = -1`` and off-diagonal weights summing to 1 per
        row, as in section 4.1 of Kohout et al. (2012); ``L @ ones = 0``.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> CF = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> L = cotangent_laplacian(C, CF)
    >>> np.allclose(L.sum(axis=1), 0.0)
    True
    """
    m = len(C)
    K = np.zeros((m, m))
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        # angle at vertex a is opposite edge (b, c)
        u = C[CF[:, b]] - C[CF[:, a]]
        v = C[CF[:, c]] - C[CF[:, a]]
        cot = np.einsum("ij,ij->i", u, v) / np.linalg.norm(np.cross(u, v), axis=1)
        np.add.at(K, (CF[:, b], CF[:, c]), 0.5 * cot)
        np.add.at(K, (CF[:, c], CF[:, b]), 0.5 * cot)
    edges = K != 0
    floor = min_weight * K[K > 0].mean()
    K = np.where(edges, np.maximum(K, floor), 0.0)
    L = K / K.sum(axis=1, keepdims=True)
    np.fill_diagonal(L, -1.0)
    return L
