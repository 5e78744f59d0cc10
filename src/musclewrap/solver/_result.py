"""The frozen result of one deformation."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np

from .._typing import FloatArray

__all__ = ["DeformationResult", "PoseContact", "Solved"]


class Solved(NamedTuple):
    """What one of a pose's solves gives back, before its result is measured."""

    x: FloatArray  # the cage
    V: FloatArray  # the fine vertices (NaN where no volume correction was found)
    iterations: int
    converged: bool
    reason: str
    history: list[tuple[float, float]]  # (energy, relative volume error) per iteration


class PoseContact(NamedTuple):
    """What a pose's contact with its bones found, kept for its finish (`Deformer.settle`).

    The finish takes them again instead of computing them anew: the targets of the
    pose's lines, the bones' `musclewrap.contact.Near` (its bounds hold wherever the
    vertices have moved since), and the bones' vertices found inside the muscle at the
    positions ``at`` (None where they were not looked for there).
    """

    targets: tuple[Any, FloatArray, FloatArray]  # current lines, samples s', rotated deltas
    near: Any  # musclewrap.contact.Near
    inside: list[Any] | None  # musclewrap.contact.Inside per bone, at ``at``
    at: FloatArray | None


@dataclass(frozen=True)
class DeformationResult:
    """Outcome of deforming a muscle to one pose.

    Attributes
    ----------
    V : (n, 3) float64 array
        Deformed fine vertices (faces unchanged).
    cage : (m, 3) float64 array
        Deformed cage vertices.
    volume_rest, volume : float
        Fine-mesh volume before and after, computed from the vertices.
    relative_volume_error : float
        ``(volume - volume_rest) / volume_rest``.
    iterations : int
        Solver iterations (for the default solver: volume-direction updates
        plus the final exact correction, plus the exact iteration's where the
        proxy's direction did not settle).
    converged : bool
        Whether the stopping criteria were met.
    reason : str
        Why the solver stopped.
    skeleton_fit_mean, skeleton_fit_max : float
        Mean and largest distance from the deformed skeleton samples
        (their mean value coordinates applied to the deformed cage) to the
        current action lines, in mesh units.
    energy : float
        ``||A x - d||**2`` of the soft conditions at the solution.
    method : str
        Solver used.
    seconds : float
        Wall time of the deformation.
    history : tuple of (float, float)
        Per iteration: energy and relative fine-volume error (``paper`` and
        ``exact`` methods; empty for the default).
    contact_vertices : int
        Vertices in contact with an obstacle after the contact finish (at its
        margin, to twice ``tol.contact`` mean edge lengths; 0 without obstacles).
    penetration_depth : float
        Deepest vertex inside an obstacle after the contact finish (0 if none),
        mesh units.
    penetration_vertices : int
        Vertices inside an obstacle after the contact finish (exact; 0 without
        obstacles).
    penetration_depth_before : float
        The same before the finish: what the solve without contact gave.
    bone_inside_depth : float
        Deepest obstacle vertex inside the result (exact, among those near it;
        with obstacles and the fine finish), mesh units.
    bone_inside_vertices : int
        How many obstacle vertices lie inside it.
    contact_moved : float
        Largest displacement of a vertex by the contact finish.
    muscle_overlap : float
        Deepest vertex inside another muscle (exact), where the muscles of a pose
        were solved together (`deform_together`); NaN otherwise.
    muscle_rounds : int
        The rounds they took (`deform_together`).
    pose : PoseContact or None
        With ``finish=False`` and obstacles: what the pose's contact found, for the
        finish of this result (`Deformer.settle`) to take again; None otherwise.
        Not compared, not in `summary`.
    """

    V: FloatArray
    cage: FloatArray
    volume_rest: float
    volume: float
    relative_volume_error: float
    iterations: int
    converged: bool
    reason: str
    skeleton_fit_mean: float
    skeleton_fit_max: float
    energy: float
    method: str
    seconds: float
    history: tuple[tuple[float, float], ...] = field(default=())
    contact_vertices: int = 0
    penetration_depth: float = 0.0
    penetration_vertices: int = 0
    penetration_depth_before: float = 0.0
    contact_moved: float = 0.0
    bone_inside_depth: float = 0.0
    bone_inside_vertices: int = 0
    muscle_overlap: float = float("nan")
    muscle_rounds: int = 0
    pose: PoseContact | None = field(default=None, repr=False, compare=False)

    @classmethod
    def failed(
        cls,
        n_vertices: int,
        n_cage: int,
        volume_rest: float,
        reason: str,
        *,
        method: str = "none",
        seconds: float = 0.0,
    ) -> DeformationResult:
        """An unconverged result without positions (all NaN), for a pose that could not be solved."""
        nan = float("nan")
        return cls(
            V=np.full((n_vertices, 3), np.nan),
            cage=np.full((n_cage, 3), np.nan),
            volume_rest=volume_rest,
            volume=nan,
            relative_volume_error=nan,
            iterations=0,
            converged=False,
            reason=reason,
            skeleton_fit_mean=nan,
            skeleton_fit_max=nan,
            energy=nan,
            method=method,
            seconds=seconds,
        )

    def summary(self) -> dict[str, object]:
        """Scalars of the result as a JSON-ready dict (no arrays)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        for k in ("V", "cage", "history", "pose"):
            d.pop(k)
        return {k: (float(v) if isinstance(v, np.floating) else v) for k, v in d.items()}
