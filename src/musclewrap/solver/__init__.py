"""Per-muscle preparation and per-pose constrained solve."""

from ..mesh import cubic_root_near
from ._deformer import METHODS, Deformer
from ._muscle import PREPARATION_FORMAT, Muscle, deform
from ._paper import solve_paper
from ._result import DeformationResult
from ._together import deform_together, facing_at_rest, meet

__all__ = [
    "METHODS",
    "PREPARATION_FORMAT",
    "DeformationResult",
    "Deformer",
    "Muscle",
    "cubic_root_near",
    "deform",
    "deform_together",
    "facing_at_rest",
    "meet",
    "solve_paper",
]
