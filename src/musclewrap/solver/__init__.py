"""Per-muscle preparation and per-pose constrained solve."""

from ._contact import ContactReport, Placed, attachment_patches, push_out
from ._cubic import cubic_root_near
from ._muscle import METHODS, Deformer, Muscle, deform
from ._paper import solve_paper
from ._result import DeformationResult

__all__ = [
    "METHODS",
    "ContactReport",
    "DeformationResult",
    "Deformer",
    "Muscle",
    "Placed",
    "attachment_patches",
    "cubic_root_near",
    "deform",
    "push_out",
    "solve_paper",
]
