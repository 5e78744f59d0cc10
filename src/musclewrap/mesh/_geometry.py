"""Small geometric quantities of triangle meshes shared across the package."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray

__all__ = ["face_areas", "half_edges", "mean_edge_length", "umbrella_laplacian"]


def half_edges(F: IntArray) -> IntArray:
    """Directed half-edges ``(3 k, 2)`` of triangles ``F``: (0,1), (1,2), (2,0) of each face."""
    return np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])


def face_areas(V: FloatArray, F: IntArray) -> FloatArray:
    """Area of every triangle."""
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def mean_edge_length(V: FloatArray, F: IntArray) -> float:
    """Mean edge length (over half-edges: on a closed mesh, the mean over its edges)."""
    e = half_edges(F)
    return float(np.mean(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)))


def umbrella_laplacian(F: IntArray, n: int) -> sp.csr_matrix:
    """Uniform ("umbrella") Laplacian: ``(U @ V)[i] = v_i - mean of its 1-ring``."""
    e = half_edges(F)
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    A = ((A + A.T) > 0).astype(np.float64)
    deg = np.asarray(A.sum(axis=1)).ravel()
    return (sp.identity(n, format="csr") - sp.diags(1.0 / deg) @ A).tocsr()
