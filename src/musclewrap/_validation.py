"""Input coercion and checks that raise ``ValueError`` naming the argument."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ._typing import FloatArray, IntArray

__all__ = ["as_faces", "as_points", "as_vertices"]


def as_points(value: npt.ArrayLike, name: str, *, min_rows: int = 1) -> FloatArray:
    """Coerce ``value`` to a finite (k, 3) float64 array.

    Parameters
    ----------
    value : array_like
        Candidate points.
    name : str
        Argument name quoted in error messages.
    min_rows : int, optional
        Minimum number of rows.

    Returns
    -------
    (k, 3) float64 array

    Raises
    ------
    ValueError
        If the shape is wrong, there are too few rows or a value is not finite.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric (k, 3) coordinates: {exc}") from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (k, 3), got {arr.shape}")
    if arr.shape[0] < min_rows:
        raise ValueError(f"{name} needs at least {min_rows} point(s), got {arr.shape[0]}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ValueError(
            f"{name} has {int(bad.sum())} non-finite (NaN/inf) point(s), first at row "
            f"{int(np.flatnonzero(bad)[0])}"
        )
    return np.ascontiguousarray(arr)


def as_vertices(V: npt.ArrayLike, name: str = "V") -> FloatArray:
    """Coerce mesh vertices to a finite (n, 3) float64 array (see `as_points`)."""
    return as_points(V, name, min_rows=4)


def as_faces(F: npt.ArrayLike, n_vertices: int, name: str = "F") -> IntArray:
    """Coerce triangle indices to a (m, 3) int64 array and check the index range.

    Parameters
    ----------
    F : array_like
        Triangle vertex indices.
    n_vertices : int
        Number of vertices the indices refer to.
    name : str, optional
        Argument name quoted in error messages.

    Returns
    -------
    (m, 3) int64 array

    Raises
    ------
    ValueError
        If the shape is wrong, the array is empty, or an index is out of range.
    """
    arr = np.asarray(F)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must be (m, 3) triangle indices, got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise ValueError(f"{name} is empty: the mesh has no triangles")
    if not np.issubdtype(arr.dtype, np.integer):
        if not np.all(np.equal(np.mod(arr, 1), 0)):
            raise ValueError(f"{name} must hold integer vertex indices")
    arr = np.ascontiguousarray(arr, dtype=np.int64)
    if arr.min() < 0 or arr.max() >= n_vertices:
        raise ValueError(
            f"{name} indices must lie in [0, {n_vertices - 1}], got range "
            f"[{int(arr.min())}, {int(arr.max())}]"
        )
    return arr
