"""Which muscle vertices can be near an obstacle: lower bounds of their signed distance."""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ._placed import Placed

__all__ = ["Near"]


@numba.njit(cache=True)
def _within_kernel(P, R, lower, reach, out):  # noqa: ANN001, ANN202 # pragma: no cover
    # the rows i with lower_i - |P_i - R_i| < reach_i, in order; returns how many
    k = 0
    for i in range(P.shape[0]):
        d0, d1, d2 = P[i, 0] - R[i, 0], P[i, 1] - R[i, 1], P[i, 2] - R[i, 2]
        if lower[i] - np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) < reach[i]:
            out[k] = i
            k += 1
    return k


class Near:
    """Which vertices can be within reach of each obstacle, by the 1-Lipschitz bound.

    Per obstacle and vertex, a lower bound of the signed distance at a
    reference position: first the grid's (`Obstacle.bounds`) at ``V``, then the
    exact distance wherever a query took it (`learn`). After a vertex moved to
    ``P`` it can be nearer the obstacle than its allowed distance only if its
    bound less its distance from the reference is, so only those are queried
    again: once the first round has found the contact, later rounds query
    little more than the vertices in contact.
    """

    def __init__(self, V: FloatArray, placed: Sequence[Placed], margin: float) -> None:
        self.V = V
        n = len(V)
        self.lower = [pl.obstacle.bounds(pl.to_obstacle(V))[0] for pl in placed]
        self.ref = [V] * len(placed)  # shared until an obstacle learns
        self.allowed = [pl.allowed(margin, n) for pl in placed]

    def deepest(self) -> float:
        """An upper bound of how far a vertex lies within its allowed distance."""
        return max(
            (
                float((a - lo).max(initial=-np.inf))
                for lo, a in zip(self.lower, self.allowed, strict=True)
            ),
            default=-np.inf,
        )

    def within(self, b: int, P: FloatArray, reach: float | FloatArray) -> IntArray:
        """Vertices whose bound for obstacle ``b`` less their move is below allowed + reach."""
        out = np.empty(len(P), dtype=np.int64)
        k = _within_kernel(
            np.ascontiguousarray(P, dtype=np.float64),
            self.ref[b],
            self.lower[b],
            self.allowed[b] + reach,
            out,
        )
        return out[:k]

    def moved(self, b: int, P: FloatArray, rows: IntArray | None = None) -> FloatArray:
        """Distance of ``P`` (all vertices, or ``rows``) from obstacle ``b``'s references."""
        R = self.ref[b] if rows is None else self.ref[b][rows]
        return np.sqrt(np.einsum("ij,ij->i", P - R, P - R))

    def rows(self, P: FloatArray, reach: float) -> list[IntArray]:
        """Per obstacle, the vertices whose distance may be below the allowed one + reach."""
        return [self.within(b, P, reach) for b in range(len(self.lower))]

    def learn(self, b: int, rows: IntArray, P: FloatArray, lower: FloatArray) -> None:
        """Obstacle ``b``'s new bounds ``lower`` at positions ``P`` of vertices ``rows``."""
        if self.ref[b] is self.V:
            self.ref[b] = self.V.copy()
        self.ref[b][rows] = P
        self.lower[b][rows] = lower
