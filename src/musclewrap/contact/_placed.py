"""An obstacle placed in a pose: the transform from the muscle's frame into the obstacle's."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..mesh import apply_transform
from ._obstacle import Obstacle

__all__ = ["Placed", "as_placed"]


@dataclass(frozen=True)
class Placed:
    """An obstacle in a pose: ``T`` maps the muscle's frame into the obstacle's frame.

    Attributes
    ----------
    obstacle : Obstacle
        The bone, in its own frame (built once, `Obstacle.cached`).
    T : (4, 4) float64 array or None
        Rigid transform from the frame of the muscle's vertices to the
        obstacle's frame (None: the same frame).
    allowance : (n,) float64 array or None
        Per muscle vertex, the smallest signed distance to this obstacle that is
        accepted in place of the margin where it is smaller (a rest overlap kept
        with ``rest_overlap = "keep"``: no vertex goes deeper than it was).
    name : str
        Quoted in reasons.
    """

    obstacle: Obstacle
    T: FloatArray | None = None
    allowance: FloatArray | None = None
    name: str = "obstacle"

    def allowed(self, margin: float, n: int) -> FloatArray:
        """Smallest accepted signed distance per muscle vertex."""
        a = np.full(n, float(margin))
        if self.allowance is not None:
            a = np.minimum(a, self.allowance)
        return a

    def to_obstacle(self, P: FloatArray) -> FloatArray:
        """Points of the muscle's frame in the obstacle's frame."""
        if self.T is None:
            return P
        return apply_transform(self.T, P)

    def to_muscle(self, P: FloatArray, *, direction: bool = False) -> FloatArray:
        """Points (or, with ``direction``, vectors) of the obstacle's frame in the muscle's."""
        if self.T is None:
            return P
        R = self.T[:3, :3]
        return P @ R if direction else (P - self.T[:3, 3]) @ R


def as_placed(obstacles: Sequence[Any] | None) -> list[Placed] | None:
    """Obstacles as `Placed` (a bare `Obstacle`: in the muscle's frame); None where there are none."""
    if not obstacles:
        return None
    return [o if isinstance(o, Placed) else Placed(o) for o in obstacles]
