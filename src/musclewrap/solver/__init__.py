"""Per-muscle preparation and per-pose constrained solve."""

from ..mesh import cubic_root_near
from ._muscle import METHODS, Deformer, Muscle, deform
from ._paper import solve_paper
from ._result import DeformationResult

__all__ = [
    "METHODS",
    "DeformationResult",
    "Deformer",
    "Muscle",
    "cubic_root_near",
    "deform",
    "solve_paper",
]
